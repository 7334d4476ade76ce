//! The fitted-clip container (`.qcf`, DESIGN section 16): a skeleton, the BVH hierarchy it came
//! from when it did, and fitted clips, as versioned little-endian binary ending in a checksum,
//! so that a damaged file is refused rather than decoded into other motion. Every count is
//! checked against the bytes left before anything is allocated, and a bad or truncated field
//! is an error naming it and its byte offset.

pub mod decoder;
pub mod fitted;
mod packed;
pub mod quantize;
pub mod timeline;

use fitted::{Fitted, FittedChannel, FittedClip, Form, KEYS_ORDER, ORDER};
use packed::{pack_codes, rice_parameter, unpack_codes, width_of, BitWriter, Knots, Packing, Places, MOST_RICE};
use quantize::{Quantized, QuantizedRotations, MAX_BITS};
use quatcurve_anim::error::{ContainerError, InputError};
use quatcurve_anim::{Animation, Joint, Property};
use quatcurve_eval::batch::MIN_KEY_NORM;
use quatcurve_eval::error::Number;
use std::fmt::Display;
use timeline::{KeyTimes, Timeline, BETWEEN_POINTS};

/// The first bytes of a container.
pub const MAGIC: [u8; 8] = *b"QCURVFIT";

/// The layout this code writes and reads.
pub const VERSION: u16 = 6;

/// Bytes of the checksum that ends a container: CRC-32 (zlib's) of every byte before it.
pub const CHECKSUM_BYTES: usize = 4;

/// Bytes before the checksum is read: the magic and the version.
const HEADER_BYTES: usize = MAGIC.len() + 2;

/// The file extension.
pub const EXTENSION: &str = "qcf";

/// Bits of a rotation control point's largest-component index.
const INDEX_BITS: u32 = 2;

/// The largest-component byte that says each control point's index follows, packed.
const SEVERAL_LARGEST: u8 = 4;

/// A container's contents.
#[derive(Clone, Debug, PartialEq)]
pub struct Container {
    /// The skeleton at rest, parents by index.
    pub joints: Vec<Joint>,
    /// The BVH hierarchy of a BVH source, so that a bake writes BVH again.
    pub bvh: Option<BvhSkeleton>,
    /// The clips.
    pub clips: Vec<FittedClip>,
}

/// A BVH source's text before `MOTION` and its frame time.
#[derive(Clone, Debug, PartialEq)]
pub struct BvhSkeleton {
    /// The hierarchy text, as the source wrote it.
    pub hierarchy: String,
    /// Seconds per source frame.
    pub frame_time: f64,
}

impl Container {
    /// The animation a bake reads: the skeleton, and each clip's channels with their knots
    /// and control points ([`FittedClip::to_clip`]).
    #[must_use]
    pub fn animation(&self) -> Animation {
        Animation {
            joints: self.joints.clone(),
            clips: self.clips.iter().map(FittedClip::to_clip).collect(),
            skins: Vec::new(),
        }
    }

    /// The container in the file at `path`.
    ///
    /// # Errors
    /// The file cannot be read, or a field of it is bad ([`ContainerError`]).
    pub fn read(path: &std::path::Path) -> Result<Self, InputError> {
        let bytes = std::fs::read(path).map_err(InputError::Read)?;
        Ok(Self::from_bytes(&bytes)?)
    }

    /// Every clip's rotation channels as tracks ([`FittedClip::rotation_tracks`]).
    #[must_use]
    pub fn rotation_tracks(&self) -> Vec<quatcurve_eval::track::Track> {
        self.clips.iter().flat_map(|c| c.rotation_tracks(&self.joints)).collect()
    }

    /// The container's bytes.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Writer::default();
        out.bytes(&MAGIC);
        out.bytes(&VERSION.to_le_bytes());
        out.u8(ORDER as u8);
        out.u8(BETWEEN_POINTS as u8);
        out.count(self.joints.len());
        for joint in &self.joints {
            out.text(&joint.name);
            out.count(joint.parent.map_or(0, |p| p + 1));
            joint.rotation.iter().chain(&joint.translation).chain(&joint.scale).for_each(|&v| out.f64(v));
        }
        match &self.bvh {
            None => out.count(0),
            Some(bvh) => {
                out.text(&bvh.hierarchy);
                out.f64(bvh.frame_time);
            }
        }
        out.count(self.clips.len());
        for clip in &self.clips {
            let section = clip_section(clip);
            out.count(section.len());
            out.bytes(&section);
        }
        out.bytes(&[0; CHECKSUM_BYTES]);
        reseal(&mut out.bytes);
        out.bytes
    }

    /// A container from its bytes.
    ///
    /// # Errors
    /// The first field that is truncated or out of its range, named, with its offset.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ContainerError> {
        let stored = Stored::from_bytes(bytes)?;
        let clips = stored.clips.into_iter().map(StoredClip::fitted).collect();
        Ok(Container { joints: stored.joints, bvh: stored.bvh, clips })
    }
}

/// A container as its bytes hold it: every field read and checked, each curve's control
/// points still codes. The container's model ([`Container`], control points in f64) and the
/// runtime decoder ([`decoder::Decoder`], in f32) are each built from it.
pub(crate) struct Stored {
    pub(crate) joints: Vec<Joint>,
    pub(crate) bvh: Option<BvhSkeleton>,
    pub(crate) clips: Vec<StoredClip>,
}

/// A clip as stored: [`FittedClip`] with each curve's codes not yet decoded.
pub(crate) struct StoredClip {
    pub(crate) name: String,
    pub(crate) span: [f64; 2],
    pub(crate) timelines: Vec<Timeline>,
    pub(crate) channels: Vec<StoredChannel>,
}

/// A channel as stored: joint, property, and its constant or curve.
pub(crate) struct StoredChannel {
    pub(crate) joint: usize,
    pub(crate) property: Property,
    pub(crate) curve: StoredCurve,
}

/// A curve as stored: its timeline, form, knot indices and codes ([`Fitted::rotation`] and
/// [`Fitted::vector`] take exactly these).
pub(crate) enum StoredCurve {
    /// A constant's value (`f32` values, as stored).
    Constant([f64; 4]),
    /// Timeline, form, knot indices and codes of a rotation curve.
    Rotation(usize, Form, Vec<u32>, QuantizedRotations),
    /// The same of a translation or scale curve.
    Vector(usize, Form, Vec<u32>, Quantized),
}

impl StoredClip {
    /// The clip in the container's model: its control points decoded.
    fn fitted(self) -> FittedClip {
        let timelines = self.timelines;
        let channels = self
            .channels
            .into_iter()
            .map(|c| {
                let curve = match c.curve {
                    StoredCurve::Constant(v) => Fitted::Constant(v),
                    StoredCurve::Rotation(line, form, knots, codes) => {
                        Fitted::rotation(&timelines, line, form, knots, codes)
                    }
                    StoredCurve::Vector(line, form, knots, codes) => {
                        Fitted::vector(&timelines, line, form, knots, codes)
                    }
                };
                FittedChannel { joint: c.joint, property: c.property, curve }
            })
            .collect();
        FittedClip { name: self.name, span: self.span, timelines, channels }
    }
}

impl Stored {
    /// Every field of a container's bytes, checked ([`Container::from_bytes`]).
    pub(crate) fn from_bytes(bytes: &[u8]) -> Result<Self, ContainerError> {
        let mut r = Reader { bytes, at: 0 };
        let magic = r.take(MAGIC.len(), "magic")?;
        if magic != MAGIC {
            return Err(r.bad_at(
                0,
                "magic",
                format!("not a quatcurve fitted-clip container (those start with {})", String::from_utf8_lossy(&MAGIC)),
            ));
        }
        let version = u16::from_le_bytes([r.u8("version")?, r.u8("version")?]);
        if version != VERSION {
            return Err(r.bad_at(
                8,
                "version",
                format!("{version}; this quatcurve reads version {VERSION} (fit the source again)"),
            ));
        }
        let Some(body) = bytes.len().checked_sub(CHECKSUM_BYTES).filter(|&body| body >= r.at) else {
            return Err(
                r.bad("checksum", format!("truncated: {CHECKSUM_BYTES} bytes needed, {} left", bytes.len() - r.at))
            );
        };
        let (said, computed) = (checksum_at(bytes, body), crc32fast::hash(&bytes[..body]));
        if said != computed {
            return Err(r.bad_at(
                body,
                "checksum",
                format!(
                    "the bytes before it hash to {computed:08x}, the container says {said:08x}: it was damaged or \
                     changed after it was written"
                ),
            ));
        }
        let mut r = Reader { bytes: &bytes[..body], at: r.at };
        r.expect("order", ORDER)?;
        r.expect("points between keys", BETWEEN_POINTS)?;
        // A joint takes at least a name length, a parent and 10 f64.
        let n = r.count("joint count", 2 + 80)?;
        let mut joints = Vec::with_capacity(n);
        for j in 0..n {
            let field = |what: &str| format!("joint {j} {what}");
            let name = r.text(&field("name"))?;
            let at = r.at;
            let parent = match r.varint(&field("parent"))? {
                0 => None,
                p if p <= n as u64 && p as usize - 1 != j => Some(p as usize - 1),
                p => return Err(r.bad_at(at, field("parent"), format!("{} is not another of the {n} joints", p - 1))),
            };
            let mut floats = [0.0; 10];
            for v in &mut floats {
                *v = r.finite_f64(&field("rest pose"))?;
            }
            let [x, y, z, w, tx, ty, tz, sx, sy, sz] = floats;
            let norm = (x * x + y * y + z * z + w * w).sqrt();
            if norm < MIN_KEY_NORM {
                return Err(r.bad_at(
                    r.at - 80,
                    field("rest pose"),
                    format!("its rotation has norm {}, below {}", Number(norm), Number(MIN_KEY_NORM)),
                ));
            }
            joints.push(Joint { name, parent, rotation: [x, y, z, w], translation: [tx, ty, tz], scale: [sx, sy, sz] });
        }
        let hierarchy = r.text("BVH hierarchy")?;
        let bvh = if hierarchy.is_empty() {
            None
        } else {
            let frame_time = r.finite_f64("BVH frame time")?;
            if frame_time <= 0.0 {
                return Err(r.bad("BVH frame time", format!("{frame_time} s is not positive")));
            }
            Some(BvhSkeleton { hierarchy, frame_time })
        };
        let clip_count = r.count("clip count", 1)?;
        let mut clips = Vec::with_capacity(clip_count);
        for c in 0..clip_count {
            let length = r.count(&format!("clip {c} length"), 1)?;
            let start = r.at;
            let clip = read_clip(&mut r, c, &joints)?;
            if r.at - start != length {
                return Err(r.bad_at(
                    start,
                    format!("clip {c} '{}'", clip.name),
                    format!("{} bytes where its length says {length}", r.at - start),
                ));
            }
            clips.push(clip);
        }
        if r.at != r.bytes.len() {
            return Err(r.bad("end", format!("{} bytes after the last clip", r.bytes.len() - r.at)));
        }
        Ok(Stored { joints, bvh, clips })
    }
}

/// Writes the checksum of a container's `bytes` again over its last [`CHECKSUM_BYTES`], for
/// tests and fuzzing that change a container's fields on purpose and want the reader to reach
/// them. Too short to hold a header and a checksum: left as it is.
pub fn reseal(bytes: &mut [u8]) {
    if let Some(body) = bytes.len().checked_sub(CHECKSUM_BYTES).filter(|&body| body >= HEADER_BYTES) {
        let hash = crc32fast::hash(&bytes[..body]);
        bytes[body..].copy_from_slice(&hash.to_le_bytes());
    }
}

/// The checksum a container says it has, in its last [`CHECKSUM_BYTES`] from `body`.
fn checksum_at(bytes: &[u8], body: usize) -> u32 {
    let mut said = [0; CHECKSUM_BYTES];
    said.copy_from_slice(&bytes[body..]);
    u32::from_le_bytes(said)
}

/// A clip's bytes in the container: what compression is counted in.
#[must_use]
pub fn clip_bytes(clip: &FittedClip) -> usize {
    clip_section(clip).len()
}

/// Property codes in a channel's tag.
const PROPERTIES: [Property; 3] = [Property::Rotation, Property::Translation, Property::Scale];

/// A clip: name, span, timelines, channels.
fn clip_section(clip: &FittedClip) -> Vec<u8> {
    let mut out = Writer::default();
    out.text(&clip.name);
    out.f64(clip.span[0]);
    out.f64(clip.span[1]);
    let channels = clip.channels.iter().map(|channel| (channel.joint, channel.property, channel.curve.parts()));
    out.clip_body(&clip.timelines, channels, Packing::Rice);
    out.bytes
}

/// A channel's stored values, whichever model holds them.
enum Parts<'x> {
    Constant(&'x [f64; 4]),
    Curve { line: usize, form: Form, knots: &'x [u32], codes: &'x Quantized, largest: Option<&'x [u8]> },
}

impl Fitted {
    fn parts(&self) -> Parts<'_> {
        match self {
            Fitted::Constant(v) => Parts::Constant(v),
            Fitted::Rotation(spline, codes) => Parts::Curve {
                line: spline.timeline,
                form: spline.form,
                knots: &spline.knots,
                codes: &codes.smallest,
                largest: Some(&codes.largest),
            },
            Fitted::Vector(spline, codes) => {
                Parts::Curve { line: spline.timeline, form: spline.form, knots: &spline.knots, codes, largest: None }
            }
        }
    }
}

impl StoredCurve {
    fn parts(&self) -> Parts<'_> {
        match self {
            StoredCurve::Constant(v) => Parts::Constant(v),
            StoredCurve::Rotation(line, form, knots, codes) => {
                Parts::Curve { line: *line, form: *form, knots, codes: &codes.smallest, largest: Some(&codes.largest) }
            }
            StoredCurve::Vector(line, form, knots, codes) => {
                Parts::Curve { line: *line, form: *form, knots, codes, largest: None }
            }
        }
    }
}

/// A channel's bytes in the container: what a fit weighs its forms by.
#[must_use]
pub fn channel_bytes(channel: &FittedChannel) -> usize {
    let mut out = Writer::default();
    write_channel(&mut out, channel.joint, channel.property, channel.curve.parts(), Packing::Rice);
    out.bytes.len()
}

/// The tag's kind of each [`Form`] (0 is a constant).
fn form_kind(form: Form) -> u8 {
    match form {
        Form::Cubic => 1,
        Form::Keys => 2,
    }
}

/// A channel: joint, tag (property in the low two bits, kind above), then its value or curve.
fn write_channel(out: &mut Writer, joint: usize, property: Property, parts: Parts, packing: Packing) {
    out.count(joint);
    let tag = PROPERTIES.iter().position(|&p| p == property).expect("a property") as u8;
    match parts {
        Parts::Constant(v) => {
            out.u8(tag);
            let n = if property == Property::Rotation { 4 } else { 3 };
            v[..n].iter().for_each(|&x| out.f32(x as f32));
        }
        Parts::Curve { line, form, knots, codes, largest } => {
            out.u8(tag | form_kind(form) << 2);
            out.curve(line, form, knots, codes, packing);
            // One index for every control point (the usual case), or each packed.
            match largest {
                None => {}
                Some(largest) if largest.iter().all(|&i| i == largest[0]) => out.u8(largest[0]),
                Some(largest) => {
                    out.u8(SEVERAL_LARGEST);
                    let mut bits = BitWriter::default();
                    largest.iter().for_each(|&i| bits.push(u64::from(i), INDEX_BITS));
                    out.bytes(&bits.finish());
                }
            }
        }
    }
}

/// Zero bytes after the runtime form's clips: a fixed-width read loads 8 bytes wherever it starts.
pub(crate) const RUNTIME_PADDING: usize = 8;

/// The clips of a checked container as the runtime decoder reads them: each clip's body
/// (timelines and channels, [`Writer::clip_body`]) with its streams at fixed widths, one after
/// another and padded with [`RUNTIME_PADDING`] zero bytes (a fixed-width read takes 8), and where each
/// body starts.
pub(crate) fn runtime_clips(clips: &[StoredClip]) -> (Vec<u8>, Vec<usize>) {
    let mut out = Writer::default();
    let mut starts = Vec::with_capacity(clips.len());
    for clip in clips {
        starts.push(out.bytes.len());
        let channels = clip.channels.iter().map(|channel| (channel.joint, channel.property, channel.curve.parts()));
        out.clip_body(&clip.timelines, channels, Packing::Fixed);
    }
    out.bytes(&[0; RUNTIME_PADDING]);
    (out.bytes, starts)
}

fn read_clip(r: &mut Reader, c: usize, joints: &[Joint]) -> Result<StoredClip, ContainerError> {
    let name = r.text(&format!("clip {c} name"))?;
    let clip = format!("clip {c} '{name}'");
    let span = [r.finite_f64(&format!("{clip} start"))?, r.finite_f64(&format!("{clip} end"))?];
    if span[1] < span[0] {
        return Err(r.bad(format!("{clip} end"), format!("{} s is before its start {} s", span[1], span[0])));
    }
    let views = r.timelines(&clip, true)?;
    let timelines: Vec<Timeline> = views
        .iter()
        .map(|view| match *view {
            KeyTimes::Even { first, last, count, .. } => Timeline::Even { first, last, count },
            KeyTimes::Listed(_) => Timeline::Listed((0..view.keys()).map(|k| view.key(k)).collect()),
        })
        .collect();
    let count = r.channel_count(&clip)?;
    let mut channels = Vec::with_capacity(count);
    for k in 0..count {
        let field = Channel { clip: &clip, index: k, joint: None };
        let (joint, property, fields) = r.channel(&field, joints, &views)?;
        let field = Channel { joint: Some(&joints[joint].name), ..field };
        let curve = match fields {
            ChannelFields::Constant(v) => StoredCurve::Constant(v),
            ChannelFields::Curve(curve, largest) => {
                let mut stream = curve.knot_stream();
                let mut knots = Vec::with_capacity(curve.knot_count);
                for i in 0..curve.knot_count {
                    let knot = stream.next();
                    knots.push(knot.map_err(|e| r.bad_at(curve.knots_at, format!("{field} knot {i}"), e.to_string()))?);
                }
                if stream.bytes_read() != curve.knot_bytes.len() {
                    let (read, length) = (stream.bytes_read(), curve.knot_bytes.len());
                    let reason = format!("{read} bytes of knots where their length says {length}");
                    return Err(r.bad_at(curve.knots_at, Sub(field, "knots"), reason));
                }
                let codes = unpack_codes(curve.codes, curve.points, curve.bits)
                    .map_err(|e| r.bad_at(curve.codes_at, Sub(field, "codes"), e.to_string()))?;
                let codes = Quantized { bits: curve.bits, low: curve.low, span: curve.span, codes };
                match largest {
                    None => StoredCurve::Vector(curve.line, curve.form, knots, codes),
                    Some(largest) => {
                        let largest = (0..curve.points).map(|i| largest.at(i)).collect();
                        let codes = QuantizedRotations { smallest: codes, largest };
                        StoredCurve::Rotation(curve.line, curve.form, knots, codes)
                    }
                }
            }
        };
        channels.push(StoredChannel { joint, property, curve });
    }
    Ok(StoredClip { name, span, timelines, channels })
}

/// A channel's name for messages: its clip, index and, once read, its joint's name.
#[derive(Clone, Copy)]
pub(crate) struct Channel<'a> {
    pub(crate) clip: &'a str,
    pub(crate) index: usize,
    pub(crate) joint: Option<&'a str>,
}

impl Display for Channel<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} channel {}", self.clip, self.index)?;
        match self.joint {
            Some(joint) => write!(f, " ({joint})"),
            None => Ok(()),
        }
    }
}

/// A channel's fields as stored, its streams not yet read.
pub(crate) enum ChannelFields<'a> {
    /// A constant's value (`f32` values, as stored).
    Constant([f64; 4]),
    /// A curve, and a rotation's largest components (`None` for a vector).
    Curve(CurveFields<'a>, Option<Largest<'a>>),
}

/// A curve's fields as stored: what the container's reader checks whole and the runtime
/// decoder reads as its cursors step.
pub(crate) struct CurveFields<'a> {
    pub(crate) line: usize,
    pub(crate) form: Form,
    /// Where its knots may lie, and how many there are.
    pub(crate) places: Places,
    pub(crate) knot_count: usize,
    /// The knots' parameter (a Rice parameter, or in the runtime form a width), their packed
    /// deltas and the offset of those.
    pub(crate) knot_parameter: u32,
    pub(crate) knot_bytes: &'a [u8],
    pub(crate) knots_at: usize,
    /// Control points, their bit width, ranges ([`Quantized`]) and packed codes, and the
    /// offset of those.
    pub(crate) points: usize,
    pub(crate) bits: u32,
    pub(crate) low: [f64; 3],
    pub(crate) span: f64,
    pub(crate) codes: &'a [u8],
    pub(crate) codes_at: usize,
}

impl<'a> CurveFields<'a> {
    /// The knots' stream.
    pub(crate) fn knot_stream(&self) -> Knots<'a> {
        Knots::new(self.knot_bytes, self.knot_parameter, self.places)
    }
}

/// A rotation curve's largest components: one for every control point, or each its own.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Largest<'a> {
    One(u8),
    Each(&'a [u8]),
}

impl Largest<'_> {
    /// Control point `i`'s.
    #[inline(always)]
    pub(crate) fn at(self, i: usize) -> u8 {
        match self {
            Largest::One(index) => index,
            Largest::Each(packed) => {
                let per_byte = 8 / INDEX_BITS as usize;
                let byte = packed.get(i / per_byte).copied().unwrap_or(0);
                (byte >> (INDEX_BITS as usize * (i % per_byte))) & ((1 << INDEX_BITS) - 1)
            }
        }
    }
}

/// Bytes being written.
#[derive(Default)]
struct Writer {
    bytes: Vec<u8>,
}

impl Writer {
    fn bytes(&mut self, b: &[u8]) {
        self.bytes.extend_from_slice(b);
    }

    fn u8(&mut self, v: u8) {
        self.bytes.push(v);
    }

    /// LEB128: seven bits a byte, low first.
    fn count(&mut self, mut v: usize) {
        loop {
            let low = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                self.u8(low);
                return;
            }
            self.u8(low | 0x80);
        }
    }

    fn f32(&mut self, v: f32) {
        self.bytes(&v.to_le_bytes());
    }

    fn f64(&mut self, v: f64) {
        self.bytes(&v.to_le_bytes());
    }

    fn text(&mut self, s: &str) {
        self.count(s.len());
        self.bytes(s.as_bytes());
    }

    /// A curve: timeline, knots ([`Self::knots`]), bit width, ranges, codes.
    fn curve(&mut self, timeline: usize, form: Form, knots: &[u32], codes: &Quantized, packing: Packing) {
        self.count(timeline);
        self.knots(knots, least_delta(form), packing);
        self.u8(codes.bits as u8);
        codes.low.iter().chain([&codes.span]).for_each(|&v| self.f32(v as f32));
        let packed = pack_codes(&codes.codes, codes.bits, packing);
        self.count(packed.len());
        self.bytes(&packed);
    }

    /// Ascending knot indices: their count, then (when there are any) a parameter, the packed
    /// deltas' byte length (a decoder steps over them to the codes without reading them) and
    /// each delta from the one before (the first's from 0) less `least`: as Rice codes of
    /// that parameter, or (the runtime's packing) at that width.
    fn knots(&mut self, knots: &[u32], least: u32, packing: Packing) {
        self.count(knots.len());
        if knots.is_empty() {
            return;
        }
        let deltas: Vec<u64> = knots
            .iter()
            .scan(0u32, |previous, &k| {
                let delta = k.checked_sub(std::mem::replace(previous, k) + least);
                Some(u64::from(delta.expect("knots ascend, keys' each once (a fit makes no other)")))
            })
            .collect();
        let mut bits = BitWriter::default();
        match packing {
            Packing::Rice => {
                let k = rice_parameter(deltas.iter().copied());
                self.u8(k as u8);
                deltas.iter().for_each(|&d| bits.rice(d, k));
            }
            Packing::Fixed => {
                let width = width_of(deltas.iter().copied());
                self.u8(width as u8);
                deltas.iter().for_each(|&d| bits.push(d, width));
            }
        }
        let packed = bits.finish();
        self.count(packed.len());
        self.bytes(&packed);
    }

    /// A clip's timelines and channels.
    fn clip_body<'x>(
        &mut self,
        timelines: &[Timeline],
        channels: impl ExactSizeIterator<Item = (usize, Property, Parts<'x>)>,
        packing: Packing,
    ) {
        self.count(timelines.len());
        for line in timelines {
            match line {
                Timeline::Even { first, last, count } => {
                    self.u8(0);
                    self.count(*count);
                    self.f64(*first);
                    self.f64(*last);
                }
                Timeline::Listed(times) => {
                    self.u8(1);
                    self.count(times.len());
                    times.iter().for_each(|&t| self.f64(t));
                }
            }
        }
        self.count(channels.len());
        for (joint, property, parts) in channels {
            write_channel(self, joint, property, parts, packing);
        }
    }
}

/// The least delta between a curve's knots: a cubic's may repeat (0), keys' are each once.
fn least_delta(form: Form) -> u32 {
    match form {
        Form::Cubic => 0,
        Form::Keys => 1,
    }
}

/// A field's name, `"{0} {1}"`, written out only for a message: loading formats no names.
#[derive(Clone, Copy)]
struct Sub<A>(A, &'static str);

impl<A: Display> Display for Sub<A> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}", self.0, self.1)
    }
}

/// Bytes being read, and where.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    #[cold]
    fn bad(&self, field: impl Display, reason: String) -> ContainerError {
        self.bad_at(self.at, field, reason)
    }

    #[cold]
    fn bad_at(&self, offset: usize, field: impl Display, reason: String) -> ContainerError {
        ContainerError { offset, field: field.to_string(), reason }
    }

    // The small reads are inlined, their messages made out of line: opening a clip is a few
    // hundred of them.
    #[inline(always)]
    fn take(&mut self, n: usize, field: impl Display + Copy) -> Result<&'a [u8], ContainerError> {
        let left = self.bytes.len() - self.at;
        if n > left {
            return Err(self.bad(field, format!("truncated: {n} bytes needed, {left} left")));
        }
        self.at += n;
        Ok(&self.bytes[self.at - n..self.at])
    }

    #[inline(always)]
    fn u8(&mut self, field: impl Display + Copy) -> Result<u8, ContainerError> {
        match self.bytes.get(self.at) {
            Some(&b) => {
                self.at += 1;
                Ok(b)
            }
            None => Err(self.bad(field, "truncated: 1 bytes needed, 0 left".into())),
        }
    }

    fn expect(&mut self, field: impl Display + Copy, value: usize) -> Result<(), ContainerError> {
        let got = self.u8(field)?;
        if usize::from(got) == value {
            Ok(())
        } else {
            Err(self.bad_at(self.at - 1, field, format!("{got}; this quatcurve reads {value}")))
        }
    }

    #[inline(always)]
    fn varint(&mut self, field: impl Display + Copy) -> Result<u64, ContainerError> {
        let start = self.at;
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.u8(field)?;
            v |= u64::from(b & 0x7f) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(self.bad_at(start, field, "a varint longer than 64 bits".into()))
    }

    /// A count of items each at least `min_bytes` long: more than the bytes left can hold is
    /// an error before anything is allocated for them.
    #[inline(always)]
    fn count(&mut self, field: impl Display + Copy, min_bytes: usize) -> Result<usize, ContainerError> {
        let start = self.at;
        let n = self.varint(field)?;
        let left = self.bytes.len() - self.at;
        match usize::try_from(n) {
            Ok(n) if n.saturating_mul(min_bytes) <= left => Ok(n),
            _ => Err(self.bad_at(start, field, format!("{n} cannot fit in the {left} bytes left"))),
        }
    }

    fn text(&mut self, field: impl Display + Copy) -> Result<String, ContainerError> {
        let n = self.count(field, 1)?;
        let start = self.at;
        let bytes = self.take(n, field)?.to_vec();
        String::from_utf8(bytes).map_err(|e| self.bad_at(start, field, format!("not UTF-8: {e}")))
    }

    #[inline(always)]
    fn finite_f64(&mut self, field: impl Display + Copy) -> Result<f64, ContainerError> {
        let v = f64::from_le_bytes(self.take(8, field)?.try_into().expect("8 bytes"));
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.bad_at(self.at - 8, field, format!("{v} is not finite")))
        }
    }

    #[inline(always)]
    fn finite_f32(&mut self, field: impl Display + Copy) -> Result<f64, ContainerError> {
        let v = f32::from_le_bytes(self.take(4, field)?.try_into().expect("4 bytes"));
        if v.is_finite() {
            Ok(f64::from(v))
        } else {
            Err(self.bad_at(self.at - 4, field, format!("{v} is not finite")))
        }
    }

    /// A clip's timelines, each key's time checked when `every_key` (else a listed one's bytes
    /// are taken as they are: the runtime decoder's, of a container checked whole before).
    // Each field's name passed as a reference (one pointer), not as its parts: the inlined reads
    // copied those through the stack, and opening a clip took 3.4 us instead of 2.1.
    #[allow(clippy::needless_borrows_for_generic_args)]
    pub(crate) fn timelines(&mut self, clip: &str, every_key: bool) -> Result<Vec<KeyTimes<'a>>, ContainerError> {
        let count = self.count(&Sub(clip, "timeline count"), 2)?;
        let mut timelines = Vec::with_capacity(count);
        for l in 0..count {
            let field = &TimelineName(clip, l);
            let kind = self.u8(field)?;
            // Listed keys take 8 bytes each; even keys take none (knot indices stay within u32).
            let keys = self.count(&Sub(field, "key count"), if kind == 1 { 8 } else { 0 })?;
            if keys > u32::MAX as usize / (BETWEEN_POINTS + 1) {
                let reason = format!("{keys} keys are more than a knot index reaches");
                return Err(self.bad(&Sub(field, "key count"), reason));
            }
            if keys < 2 {
                return Err(self.bad(field, format!("{keys} keys; a timeline has at least 2")));
            }
            timelines.push(match kind {
                0 => {
                    let (first, last) = (self.finite_f64(field)?, self.finite_f64(field)?);
                    if last <= first {
                        return Err(self.bad(field, format!("its last key {last} s is not after its first {first} s")));
                    }
                    KeyTimes::even(first, last, keys)
                }
                1 if every_key => {
                    let start = self.at;
                    let mut previous = f64::NEG_INFINITY;
                    for k in 0..keys {
                        let key = &KeyName(*field, k);
                        let t = self.finite_f64(key)?;
                        if t <= previous {
                            return Err(self.bad_at(self.at - 8, key, format!("{t} s is not after the key before")));
                        }
                        previous = t;
                    }
                    KeyTimes::Listed(&self.bytes[start..self.at])
                }
                1 => KeyTimes::Listed(self.take(8 * keys, field)?),
                other => return Err(self.bad(field, format!("kind {other} is neither 0 (even) nor 1 (listed)"))),
            });
        }
        Ok(timelines)
    }

    /// A clip's channel count.
    // Each field's name passed as a reference (one pointer), not as its parts: the inlined reads
    // copied those through the stack, and opening a clip took 3.4 us instead of 2.1.
    #[allow(clippy::needless_borrows_for_generic_args)]
    pub(crate) fn channel_count(&mut self, clip: &str) -> Result<usize, ContainerError> {
        // A channel takes at least a joint, a tag and three f32.
        self.count(&Sub(clip, "channel count"), 14)
    }

    /// A channel's joint, property and fields, its streams not read. Inlined, as the curve's
    /// reader below: their results, returned through memory, were read back in wider loads
    /// than they were written in, which stalled opening a clip (2.1 us, not 2.0).
    // Each field's name passed as a reference (one pointer), not as its parts: the inlined reads
    // copied those through the stack, and opening a clip took 3.4 us instead of 2.1.
    #[allow(clippy::needless_borrows_for_generic_args)]
    #[inline(always)]
    pub(crate) fn channel(
        &mut self,
        field: &Channel,
        joints: &[Joint],
        timelines: &[KeyTimes],
    ) -> Result<(usize, Property, ChannelFields<'a>), ContainerError> {
        let joint = self.varint(&Sub(field, "joint"))? as usize;
        if joint >= joints.len() {
            return Err(self.bad(&Sub(field, "joint"), format!("{joint} is not one of the {} joints", joints.len())));
        }
        let field = &Channel { joint: Some(&joints[joint].name), ..*field };
        let tag = self.u8(&Sub(field, "tag"))?;
        let property = *PROPERTIES.get(usize::from(tag & 3)).ok_or_else(|| {
            self.bad(&Sub(field, "tag"), format!("property {} is not 0-2 (rotation, translation, scale)", tag & 3))
        })?;
        let rotation = property == Property::Rotation;
        let form = match tag >> 2 {
            0 => None,
            1 => Some(Form::Cubic),
            2 => Some(Form::Keys),
            other => {
                let reason = format!("kind {other} is none of 0 (constant), 1 (cubic) and 2 (keys)");
                return Err(self.bad(&Sub(field, "tag"), reason));
            }
        };
        let Some(form) = form else {
            let mut v = [0.0; 4];
            for x in v.iter_mut().take(if rotation { 4 } else { 3 }) {
                *x = self.finite_f32(&Sub(field, "value"))?;
            }
            return Ok((joint, property, ChannelFields::Constant(v)));
        };
        let curve = self.curve(field, timelines, form)?;
        if !rotation {
            return Ok((joint, property, ChannelFields::Curve(curve, None)));
        }
        let name = &Sub(field, "largest components");
        let largest = match self.u8(name)? {
            one @ 0..=3 => Largest::One(one),
            SEVERAL_LARGEST => Largest::Each(self.take((curve.points * INDEX_BITS as usize).div_ceil(8), name)?),
            other => {
                return Err(self.bad_at(self.at - 1, name, format!("{other} is neither 0-3 nor {SEVERAL_LARGEST}")))
            }
        };
        Ok((joint, property, ChannelFields::Curve(curve, Some(largest))))
    }

    /// A curve's timeline, knots and codes in `form` (see [`Writer::curve`]): every field
    /// checked but the streams', whose bytes are taken as they are.
    #[inline(always)]
    // Each field's name passed as a reference (one pointer), not as its parts: the inlined reads
    // copied those through the stack, and opening a clip took 3.4 us instead of 2.1.
    #[allow(clippy::needless_borrows_for_generic_args)]
    fn curve(
        &mut self,
        field: &Channel,
        timelines: &[KeyTimes],
        form: Form,
    ) -> Result<CurveFields<'a>, ContainerError> {
        let line = self.varint(&Sub(field, "timeline"))? as usize;
        let timeline = timelines.get(line).ok_or_else(|| {
            self.bad(&Sub(field, "timeline"), format!("{line} is not one of the clip's {}", timelines.len()))
        })?;
        // Interior knots: strictly inside the timeline's samples (a cubic's, at most ORDER - 1
        // at one) or keys (each once), and the control points they make.
        let least = least_delta(form);
        let (places, order) = match form {
            Form::Cubic => (Places { unit: "sample", last: timeline.samples() - 1, repeats: ORDER - 1, least }, ORDER),
            Form::Keys => (Places { unit: "key", last: timeline.keys() - 1, repeats: 1, least }, KEYS_ORDER),
        };
        let name = &Sub(field, "knot count");
        let start = self.at;
        // A Rice code takes a bit at least: the count is held to the bytes left, and to the
        // knots the curve can have, before anything is allocated for them.
        let knot_count = self.count(name, 0)?;
        let most = places.most();
        if knot_count > most {
            return Err(self.bad_at(start, name, format!("{knot_count} knots; its timeline has room for {most}")));
        }
        let left = self.bytes.len() - self.at;
        if knot_count > 8 * left {
            let reason = format!("{knot_count} knots of a bit at least cannot fit in the {left} bytes left");
            return Err(self.bad_at(start, name, reason));
        }
        let (mut knot_parameter, mut knot_bytes, mut knots_at) = (0, &self.bytes[..0], self.at);
        if knot_count > 0 {
            let name = &Sub(field, "knot Rice parameter");
            knot_parameter = u32::from(self.u8(name)?);
            if knot_parameter > MOST_RICE {
                return Err(self.bad_at(self.at - 1, name, format!("{knot_parameter} is more than {MOST_RICE}")));
            }
            let name = &Sub(field, "knots");
            let length = self.count(name, 1)?;
            knots_at = self.at;
            knot_bytes = self.take(length, name)?;
        }
        let bits = u32::from(self.u8(&Sub(field, "bit width"))?);
        if !(1..=MAX_BITS).contains(&bits) {
            return Err(self.bad(&Sub(field, "bit width"), format!("{bits} is not 1-{MAX_BITS}")));
        }
        let mut ranges = [0.0; 4];
        for (i, v) in ranges.iter_mut().enumerate() {
            let name = &Sub(field, if i < 3 { "low" } else { "span" });
            *v = self.finite_f32(name)?;
            if i == 3 && *v < 0.0 {
                return Err(self.bad_at(self.at - 4, name, format!("{v} is negative")));
            }
        }
        let name = &Sub(field, "codes");
        let length = self.count(name, 1)?;
        let codes_at = self.at;
        let codes = self.take(length, name)?;
        let [l0, l1, l2, span] = ranges;
        Ok(CurveFields {
            line,
            form,
            places,
            knot_count,
            knot_parameter,
            knot_bytes,
            knots_at,
            points: knot_count + order,
            bits,
            low: [l0, l1, l2],
            span,
            codes,
            codes_at,
        })
    }
}

/// A timeline's name for messages.
#[derive(Clone, Copy)]
struct TimelineName<'a>(&'a str, usize);

impl Display for TimelineName<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} timeline {}", self.0, self.1)
    }
}

/// A listed timeline's key's name for messages.
#[derive(Clone, Copy)]
struct KeyName<'a>(TimelineName<'a>, usize);

impl Display for KeyName<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} key {}", self.0, self.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quantize;
    use quatcurve_core::quat::{QuatF64, Vec3F64};

    /// Three joints: rotation and vector curves of both forms (a vector's with a knot of
    /// multiplicity 3), a constant.
    pub(crate) fn container() -> Container {
        let timelines =
            vec![Timeline::Even { first: 0.0, last: 2.0, count: 61 }, Timeline::Listed(vec![0.0, 0.5, 2.0])];
        let turns: Vec<QuatF64> =
            (0..8).map(|i| QuatF64::from_rotation_vector(Vec3F64::new(0.2 * f64::from(i), 0.1, -0.3))).collect();
        let points: Vec<[f64; 3]> = (0..7).map(|i| [f64::from(i), 10.0, -0.5 * f64::from(i)]).collect();
        let channels = vec![
            FittedChannel {
                joint: 0,
                property: Property::Rotation,
                curve: Fitted::rotation(
                    &timelines,
                    0,
                    Form::Cubic,
                    vec![50, 100, 150, 200],
                    quantize::rotations(&turns, 1e-4),
                ),
            },
            FittedChannel {
                joint: 1,
                property: Property::Translation,
                curve: Fitted::vector(&timelines, 1, Form::Cubic, vec![3, 3, 3], Quantized::of(&points, 1e-3)),
            },
            FittedChannel { joint: 1, property: Property::Rotation, curve: Fitted::constant([0.0, 0.0, 0.6, 0.8]) },
            FittedChannel {
                joint: 0,
                property: Property::Translation,
                curve: Fitted::vector(&timelines, 0, Form::Keys, vec![10, 30, 31], Quantized::of(&points[..5], 1e-3)),
            },
            FittedChannel {
                joint: 2,
                property: Property::Rotation,
                curve: Fitted::rotation(&timelines, 1, Form::Keys, vec![1], quantize::rotations(&turns[5..], 1e-3)),
            },
        ];
        Container {
            joints: vec![
                Joint::at("root".into(), None, [0.0; 3]),
                Joint::at("tip".into(), Some(0), [0.0, 10.0, 0.0]),
                Joint::at("end".into(), Some(1), [0.0, 5.0, 0.0]),
            ],
            bvh: Some(BvhSkeleton { hierarchy: "HIERARCHY\n".into(), frame_time: 1.0 / 30.0 }),
            clips: vec![FittedClip { name: "turn".into(), span: [0.0, 2.0], timelines, channels }],
        }
    }

    #[test]
    fn a_container_reads_back_what_was_written_to_the_bit() {
        let container = container();
        let bytes = container.to_bytes();
        assert_eq!(Container::from_bytes(&bytes).unwrap(), container);
    }

    #[test]
    fn every_random_change_of_a_container_is_refused() {
        let bytes = container().to_bytes();
        // xorshift64: the same 300 changes every run.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |below: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % below as u64) as usize
        };
        let mut by_field = std::collections::BTreeMap::<String, usize>::new();
        for _ in 0..300 {
            let mut changed = bytes.clone();
            let at = next(changed.len());
            match next(4) {
                0 => changed[at] ^= 1 << next(8),
                1 => changed[at] = changed[at].wrapping_add(1 + next(255) as u8),
                2 => drop(changed.drain(at..(at + 1 + next(16)).min(bytes.len()))),
                _ => changed.splice(at..at, (0..1 + next(16)).map(|_| next(256) as u8)).for_each(drop),
            }
            let e = Container::from_bytes(&changed).expect_err("a changed container was read");
            let decoder = decoder::Decoder::from_bytes(&changed).expect_err("a changed container was decoded");
            assert_eq!(decoder, e, "the decoder reads as the container does");
            *by_field.entry(e.field).or_default() += 1;
        }
        eprintln!("300 random changes refused by field: {by_field:?}");
        // Everything past the header is caught by the checksum.
        assert!(by_field["checksum"] >= 280, "{by_field:?}");
    }

    #[test]
    fn every_truncation_and_bad_field_is_named() {
        let bytes = container().to_bytes();
        for cut in 0..bytes.len() {
            let e = Container::from_bytes(&bytes[..cut]).unwrap_err();
            assert!(e.reason.contains("truncated") || e.field == "checksum", "cut at {cut}: {e}");
            // With the checksum made right again, the fields say what is missing.
            let mut resealed = bytes[..cut].to_vec();
            reseal(&mut resealed);
            let e = Container::from_bytes(&resealed).unwrap_err();
            assert!(e.reason.contains("truncated") || e.reason.contains("cannot fit"), "cut at {cut}, resealed: {e}");
        }
        let mut longer = bytes.clone();
        longer.insert(bytes.len() - CHECKSUM_BYTES, 0);
        assert!(Container::from_bytes(&longer).unwrap_err().to_string().contains(": checksum: the bytes before it"));
        reseal(&mut longer);
        assert_eq!(
            Container::from_bytes(&longer).unwrap_err().to_string(),
            format!("byte {}: end: 1 bytes after the last clip", bytes.len() - CHECKSUM_BYTES)
        );
        let mut magic = bytes.clone();
        magic[0] = b'X';
        assert!(Container::from_bytes(&magic).unwrap_err().to_string().starts_with("byte 0: magic: not a quatcurve"));
        let mut version = bytes.clone();
        version[8] = 9;
        assert_eq!(
            Container::from_bytes(&version).unwrap_err().to_string(),
            "byte 8: version: 9; this quatcurve reads version 6 (fit the source again)"
        );
        // Knots a fit never makes: outside the samples, or more than ORDER - 1 at one; keys
        // outside the keys (keys' deltas are coded less one, so none is 0 or kept twice).
        for (form, channel, knots, reason) in [
            (Form::Cubic, 1, vec![0], "sample 0 is not inside 1..10"),
            (Form::Cubic, 1, vec![3, 3, 3, 3], "sample 3 repeated 4 times; at most 3"),
            (Form::Cubic, 1, vec![10], "sample 10 is not inside 1..10"),
            (Form::Keys, 3, vec![60], "key 60 is not inside 1..60"),
            (Form::Keys, 3, vec![5, 60], "key 60 is not inside 1..60"),
        ] {
            let mut bad = container();
            let clip = &mut bad.clips[0];
            let controls = knots.len() + if form == Form::Cubic { ORDER } else { 2 };
            let line = if form == Form::Cubic { 1 } else { 0 };
            let codes = Quantized::of(&vec![[0.0; 3]; controls], 1e-3);
            clip.channels[channel].curve = Fitted::vector(&clip.timelines, line, form, knots.clone(), codes);
            let e = Container::from_bytes(&bad.to_bytes()).unwrap_err();
            assert!(e.field.starts_with(&format!("clip 0 'turn' channel {channel} (")), "{knots:?}: {e}");
            assert!(e.field.contains(") knot"), "{knots:?}: {e}");
            assert_eq!(e.reason, reason, "{knots:?}");
        }
        let mut still = container();
        still.joints[1].rotation = [0.0; 4];
        let e = Container::from_bytes(&still.to_bytes()).unwrap_err();
        assert_eq!(e.to_string(), "byte 104: joint 1 rest pose: its rotation has norm 0, below 1e-6");
        let mut parent = bytes;
        // Joint 0's name "root" (length byte at 13, text 14..18) and then its parent.
        parent[18] = 1;
        reseal(&mut parent);
        assert_eq!(
            Container::from_bytes(&parent).unwrap_err().to_string(),
            "byte 18: joint 0 parent: 0 is not another of the 3 joints"
        );
    }
}
