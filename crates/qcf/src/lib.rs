//! The fitted-clip container (`.qcf`, DESIGN section 16): a skeleton, the BVH hierarchy it came
//! from when it did, and fitted clips, as versioned little-endian binary ending in a checksum,
//! so that a damaged file is refused rather than decoded into other motion. Every count is
//! checked against the bytes left before anything is allocated, and a bad or truncated field
//! is an error naming it and its byte offset.

pub mod decoder;
pub mod fitted;
pub mod quantize;
pub mod timeline;

use fitted::{Fitted, FittedChannel, FittedClip, Form, ORDER};
use quantize::{Quantized, QuantizedRotations, MAX_BITS};
use quatcurve_anim::error::{ContainerError, InputError};
use quatcurve_anim::{Animation, Joint, Property};
use quatcurve_eval::batch::MIN_KEY_NORM;
use quatcurve_eval::error::Number;
use std::fmt::Display;
use timeline::{Timeline, BETWEEN_POINTS};

/// The first bytes of a container.
pub const MAGIC: [u8; 8] = *b"QCURVFIT";

/// The layout this code writes and reads.
pub const VERSION: u16 = 5;

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
    out.count(clip.timelines.len());
    for line in &clip.timelines {
        match line {
            Timeline::Even { first, last, count } => {
                out.u8(0);
                out.count(*count);
                out.f64(*first);
                out.f64(*last);
            }
            Timeline::Listed(times) => {
                out.u8(1);
                out.count(times.len());
                times.iter().for_each(|&t| out.f64(t));
            }
        }
    }
    out.count(clip.channels.len());
    for channel in &clip.channels {
        write_channel(&mut out, channel);
    }
    out.bytes
}

/// A channel's bytes in the container: what a fit weighs its forms by.
#[must_use]
pub fn channel_bytes(channel: &FittedChannel) -> usize {
    let mut out = Writer::default();
    write_channel(&mut out, channel);
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
fn write_channel(out: &mut Writer, channel: &FittedChannel) {
    out.count(channel.joint);
    let property = PROPERTIES.iter().position(|&p| p == channel.property).expect("a property") as u8;
    let vector = |out: &mut Writer, v: &[f64]| v.iter().for_each(|&x| out.f32(x as f32));
    match &channel.curve {
        Fitted::Constant(v) => {
            out.u8(property);
            vector(out, if channel.property == Property::Rotation { &v[..] } else { &v[..3] });
        }
        Fitted::Rotation(spline, codes) => {
            out.u8(property | form_kind(spline.form) << 2);
            out.curve(spline.timeline, spline.form, &spline.knots, &codes.smallest);
            // One index for every control point (the usual case), or each packed.
            match codes.largest.iter().all(|&i| i == codes.largest[0]) {
                true => out.u8(codes.largest[0]),
                false => {
                    out.u8(SEVERAL_LARGEST);
                    let mut bits = BitWriter::default();
                    codes.largest.iter().for_each(|&i| bits.push(u64::from(i), INDEX_BITS));
                    out.bytes(&bits.finish());
                }
            }
        }
        Fitted::Vector(spline, codes) => {
            out.u8(property | form_kind(spline.form) << 2);
            out.curve(spline.timeline, spline.form, &spline.knots, codes);
        }
    }
}

fn read_clip(r: &mut Reader, c: usize, joints: &[Joint]) -> Result<StoredClip, ContainerError> {
    let name = r.text(&format!("clip {c} name"))?;
    let clip = format!("clip {c} '{name}'");
    let span = [r.finite_f64(&format!("{clip} start"))?, r.finite_f64(&format!("{clip} end"))?];
    if span[1] < span[0] {
        return Err(r.bad(format!("{clip} end"), format!("{} s is before its start {} s", span[1], span[0])));
    }
    let count = r.count(&format!("{clip} timeline count"), 2)?;
    let mut timelines = Vec::with_capacity(count);
    for l in 0..count {
        let field = format!("{clip} timeline {l}");
        let kind = r.u8(&field)?;
        // Listed keys take 8 bytes each; even keys take none (knot indices stay within u32).
        let keys = r.count(&format!("{field} key count"), if kind == 1 { 8 } else { 0 })?;
        if keys > u32::MAX as usize / (BETWEEN_POINTS + 1) {
            return Err(r.bad(format!("{field} key count"), format!("{keys} keys are more than a knot index reaches")));
        }
        if keys < 2 {
            return Err(r.bad(&field, format!("{keys} keys; a timeline has at least 2")));
        }
        let line = match kind {
            0 => {
                let (first, last) = (r.finite_f64(&field)?, r.finite_f64(&field)?);
                if last <= first {
                    return Err(r.bad(&field, format!("its last key {last} s is not after its first {first} s")));
                }
                Timeline::Even { first, last, count: keys }
            }
            1 => {
                let mut times = Vec::with_capacity(keys);
                for k in 0..keys {
                    let t = r.finite_f64(&format!("{field} key {k}"))?;
                    if times.last().is_some_and(|&p| t <= p) {
                        return Err(r.bad(format!("{field} key {k}"), format!("{t} s is not after the key before")));
                    }
                    times.push(t);
                }
                Timeline::Listed(times)
            }
            other => return Err(r.bad(&field, format!("kind {other} is neither 0 (even) nor 1 (listed)"))),
        };
        timelines.push(line);
    }
    // A channel takes at least a joint, a tag and three f32.
    let count = r.count(&format!("{clip} channel count"), 14)?;
    let mut channels = Vec::with_capacity(count);
    for k in 0..count {
        let field = format!("{clip} channel {k}");
        let joint = r.varint(Sub(&field, "joint"))? as usize;
        if joint >= joints.len() {
            return Err(r.bad(Sub(&field, "joint"), format!("{joint} is not one of the {} joints", joints.len())));
        }
        let field = format!("{field} ({})", joints[joint].name);
        let tag = r.u8(Sub(&field, "tag"))?;
        let property = *PROPERTIES.get(usize::from(tag & 3)).ok_or_else(|| {
            r.bad(Sub(&field, "tag"), format!("property {} is not 0-2 (rotation, translation, scale)", tag & 3))
        })?;
        let rotation = property == Property::Rotation;
        let form = match tag >> 2 {
            0 => None,
            1 => Some(Form::Cubic),
            2 => Some(Form::Keys),
            other => {
                return Err(
                    r.bad(Sub(&field, "tag"), format!("kind {other} is none of 0 (constant), 1 (cubic) and 2 (keys)"))
                )
            }
        };
        let curve = match form {
            None => {
                let mut v = [0.0; 4];
                for x in v.iter_mut().take(if rotation { 4 } else { 3 }) {
                    *x = r.finite_f32(Sub(&field, "value"))?;
                }
                StoredCurve::Constant(v)
            }
            Some(form) => {
                let (line, knots, codes) = r.curve(&field, &timelines, form)?;
                if rotation {
                    let name = Sub(&field, "largest components");
                    let largest = match r.u8(name)? {
                        one @ 0..=3 => vec![one; codes.codes.len()],
                        SEVERAL_LARGEST => {
                            let n = codes.codes.len();
                            let mut bits = BitReader::new(r.take((n * INDEX_BITS as usize).div_ceil(8), name)?);
                            (0..n).map(|_| bits.take(INDEX_BITS).map_or(0, |i| i as u8)).collect()
                        }
                        other => {
                            return Err(r.bad_at(
                                r.at - 1,
                                name,
                                format!("{other} is neither 0-3 nor {SEVERAL_LARGEST}"),
                            ))
                        }
                    };
                    StoredCurve::Rotation(line, form, knots, QuantizedRotations { smallest: codes, largest })
                } else {
                    StoredCurve::Vector(line, form, knots, codes)
                }
            }
        };
        channels.push(StoredChannel { joint, property, curve });
    }
    Ok(StoredClip { name, span, timelines, channels })
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
    fn curve(&mut self, timeline: usize, form: Form, knots: &[u32], codes: &Quantized) {
        self.count(timeline);
        self.knots(knots, least_delta(form));
        self.u8(codes.bits as u8);
        codes.low.iter().chain([&codes.span]).for_each(|&v| self.f32(v as f32));
        let packed = pack_codes(&codes.codes, codes.bits);
        self.count(packed.len());
        self.bytes(&packed);
    }

    /// Ascending knot indices: their count, then (when there are any) a Rice parameter and
    /// each delta from the one before (the first's from 0) less `least`, as Rice codes.
    fn knots(&mut self, knots: &[u32], least: u32) {
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
        let k = rice_parameter(deltas.iter().copied());
        self.u8(k as u8);
        let mut bits = BitWriter::default();
        deltas.iter().for_each(|&d| bits.rice(d, k));
        self.bytes(&bits.finish());
    }
}

/// Control points per block of Rice parameters.
const BLOCK: usize = 16;

/// Bits of a block's Rice parameter.
const RICE_BITS: u32 = 5;

/// The largest Rice parameter.
const MOST_RICE: u32 = (1 << RICE_BITS) - 1;

/// The least delta between a curve's knots: a cubic's may repeat (0), keys' are each once.
fn least_delta(form: Form) -> u32 {
    match form {
        Form::Cubic => 0,
        Form::Keys => 1,
    }
}

/// Each code's prediction from the points before it: the previous code for the second point
/// (`two_back` is `None`), the line through the two before it after that (a smooth curve's
/// control points lie nearly on one). The first point is stored whole.
fn predicted(two_back: Option<&[u32; 3]>, last: &[u32; 3], c: usize) -> i64 {
    match two_back {
        None => i64::from(last[c]),
        Some(two_back) => 2 * i64::from(last[c]) - i64::from(two_back[c]),
    }
}

/// Bits of `z` as a Rice code of parameter `k`: the quotient `z >> k` in unary (that many
/// one bits and a zero), then the low `k` bits.
fn rice_bits(z: u64, k: u32) -> u64 {
    (z >> k) + 1 + u64::from(k)
}

/// The Rice parameter (0 to [`MOST_RICE`]) that codes `values` in the fewest bits.
fn rice_parameter(values: impl Iterator<Item = u64> + Clone) -> u32 {
    (0..=MOST_RICE).min_by_key(|&k| values.clone().map(|z| rice_bits(z, k)).sum::<u64>()).unwrap_or(0)
}

/// Codes packed low bit first: the first point's at `bits` each, then per block of [`BLOCK`]
/// points each component's Rice parameter ([`RICE_BITS`], the one of fewest bits for the
/// block) and the points' zigzagged residuals from [`predicted`] as Rice codes. Residuals
/// are about Laplacian, which Rice codes fit: 4-7% fewer bytes than one width per block, for
/// about twice the time to unpack (a code's length is known only once it is read).
fn pack_codes(codes: &[[u32; 3]], bits: u32) -> Vec<u8> {
    let mut out = BitWriter::default();
    let Some(first) = codes.first() else { return out.finish() };
    first.iter().for_each(|&c| out.push(u64::from(c), bits));
    let zigzag = |i: usize, c: usize| {
        let r = i64::from(codes[i][c]) - predicted(i.checked_sub(2).map(|b| &codes[b]), &codes[i - 1], c);
        ((r << 1) ^ (r >> 63)) as u64
    };
    for block in (1..codes.len()).step_by(BLOCK) {
        let points = block..(block + BLOCK).min(codes.len());
        let ks: [u32; 3] = std::array::from_fn(|c| rice_parameter(points.clone().map(|i| zigzag(i, c))));
        ks.iter().for_each(|&k| out.push(u64::from(k), RICE_BITS));
        for i in points {
            for (c, &k) in ks.iter().enumerate() {
                out.rice(zigzag(i, c), k);
            }
        }
    }
    out.finish()
}

/// Why packed control-point codes do not decode within their width.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
enum CodeFault {
    /// The bytes end inside a point.
    #[error("the packed codes end in control point {0}")]
    End(usize),
    /// A code outside its width.
    #[error("control point {point} component {component} decodes to {value}, outside {bits} bits")]
    Outside { point: usize, component: usize, value: i64, bits: u32 },
    /// A residual's unary run longer than any residual of the width.
    #[error("control point {point} component {component}: a residual's quotient {quotient} is larger than any of {bits} bits")]
    Runaway { point: usize, component: usize, quotient: u64, bits: u32 },
}

/// Why a knot read is not one of the places the curve may have.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
enum KnotFault {
    /// A knot outside the timeline's interior.
    #[error("{unit} {at} is not inside 1..{last}")]
    Outside { unit: &'static str, at: u64, last: usize },
    /// A knot repeated more often than the curve's order allows.
    #[error("{unit} {at} repeated {} times; at most {most}", most + 1)]
    Repeated { unit: &'static str, at: u64, most: usize },
}

/// `n` points' codes of [`pack_codes`], each checked to lie within `bits`.
fn unpack_codes(packed: &[u8], n: usize, bits: u32) -> Result<Vec<[u32; 3]>, CodeFault> {
    let mut input = BitReader::new(packed);
    let end = |i: usize| move || CodeFault::End(i);
    let mut codes: Vec<[u32; 3]> = Vec::with_capacity(n);
    if n == 0 {
        return Ok(codes);
    }
    let most = (1i64 << bits) - 1;
    let outside = |point: usize, component: usize, value: i64| CodeFault::Outside { point, component, value, bits };
    // The first point whole; then blocks of residuals, each after its three Rice parameters.
    let mut first = [0u32; 3];
    for (c, code) in first.iter_mut().enumerate() {
        let value = input.take(bits).ok_or_else(end(0))? as i64;
        if !(0..=most).contains(&value) {
            return Err(outside(0, c, value));
        }
        *code = value as u32;
    }
    codes.push(first);
    // A residual of a code within `bits` from a prediction within `bits + 1`, zigzagged.
    let most_zigzag = 1u64 << (bits + 2);
    // The two points before the next, kept out of `codes` so that they stay in registers.
    let (mut two_back, mut last): (Option<[u32; 3]>, [u32; 3]) = (None, first);
    for block in (1..n).step_by(BLOCK) {
        let mut ks = [0; 3];
        for k in &mut ks {
            *k = input.take(RICE_BITS).ok_or_else(end(block))? as u32;
        }
        for i in block..(block + BLOCK).min(n) {
            let mut point = [0u32; 3];
            for c in 0..3 {
                let (quotient, low) = input.rice(ks[c]).ok_or_else(end(i))?;
                if quotient > most_zigzag >> ks[c] {
                    return Err(CodeFault::Runaway { point: i, component: c, quotient, bits });
                }
                let z = (quotient << ks[c]) | low;
                let r = (z >> 1) as i64 ^ -((z & 1) as i64);
                let value = predicted(two_back.as_ref(), &last, c).wrapping_add(r);
                if !(0..=most).contains(&value) {
                    return Err(outside(i, c, value));
                }
                point[c] = value as u32;
            }
            codes.push(point);
            two_back = Some(last);
            last = point;
        }
    }
    Ok(codes)
}

/// A field's name, `"{0} {1}"`, written out only for a message: loading formats no names.
#[derive(Clone, Copy)]
struct Sub<'a>(&'a str, &'a str);

impl Display for Sub<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}", self.0, self.1)
    }
}

/// Bytes being read, and where.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn bad(&self, field: impl Display, reason: String) -> ContainerError {
        self.bad_at(self.at, field, reason)
    }

    fn bad_at(&self, offset: usize, field: impl Display, reason: String) -> ContainerError {
        ContainerError { offset, field: field.to_string(), reason }
    }

    fn take(&mut self, n: usize, field: impl Display + Copy) -> Result<&[u8], ContainerError> {
        let left = self.bytes.len() - self.at;
        if n > left {
            return Err(self.bad(field, format!("truncated: {n} bytes needed, {left} left")));
        }
        self.at += n;
        Ok(&self.bytes[self.at - n..self.at])
    }

    fn u8(&mut self, field: impl Display + Copy) -> Result<u8, ContainerError> {
        Ok(self.take(1, field)?[0])
    }

    fn expect(&mut self, field: impl Display + Copy, value: usize) -> Result<(), ContainerError> {
        let got = self.u8(field)?;
        if usize::from(got) == value {
            Ok(())
        } else {
            Err(self.bad_at(self.at - 1, field, format!("{got}; this quatcurve reads {value}")))
        }
    }

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

    fn finite_f64(&mut self, field: impl Display + Copy) -> Result<f64, ContainerError> {
        let v = f64::from_le_bytes(self.take(8, field)?.try_into().expect("8 bytes"));
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.bad_at(self.at - 8, field, format!("{v} is not finite")))
        }
    }

    fn finite_f32(&mut self, field: impl Display + Copy) -> Result<f64, ContainerError> {
        let v = f32::from_le_bytes(self.take(4, field)?.try_into().expect("4 bytes"));
        if v.is_finite() {
            Ok(f64::from(v))
        } else {
            Err(self.bad_at(self.at - 4, field, format!("{v} is not finite")))
        }
    }

    /// A curve's timeline, knots and codes in `form` (see [`Writer::curve`]), each checked.
    fn curve(
        &mut self,
        field: &str,
        timelines: &[Timeline],
        form: Form,
    ) -> Result<(usize, Vec<u32>, Quantized), ContainerError> {
        let line = self.varint(Sub(field, "timeline"))? as usize;
        let timeline = timelines.get(line).ok_or_else(|| {
            self.bad(Sub(field, "timeline"), format!("{line} is not one of the clip's {}", timelines.len()))
        })?;
        // Interior knots: strictly inside the timeline's samples (a cubic's, at most ORDER - 1
        // at one) or keys (each once), and the control points they make.
        let (unit, last, repeats, controls) = match form {
            Form::Cubic => ("sample", timeline.samples() - 1, ORDER - 1, ORDER),
            Form::Keys => ("key", timeline.keys() - 1, 1, 2),
        };
        // Every interior place, each taken `repeats` times at most.
        let most = (last - 1) * repeats;
        let knots = self.knots(field, most, least_delta(form), |knots, at| {
            if at == 0 || at >= last as u64 {
                return Err(KnotFault::Outside { unit, at, last });
            }
            if knots.len() >= repeats && knots[knots.len() - repeats..].iter().all(|&p| u64::from(p) == at) {
                return Err(KnotFault::Repeated { unit, at, most: repeats });
            }
            Ok(())
        })?;
        let controls = knots.len() + controls;
        let bits = u32::from(self.u8(Sub(field, "bit width"))?);
        if !(1..=MAX_BITS).contains(&bits) {
            return Err(self.bad(Sub(field, "bit width"), format!("{bits} is not 1-{MAX_BITS}")));
        }
        let mut ranges = [0.0; 4];
        for (i, v) in ranges.iter_mut().enumerate() {
            let name = Sub(field, if i < 3 { "low" } else { "span" });
            *v = self.finite_f32(name)?;
            if i == 3 && *v < 0.0 {
                return Err(self.bad_at(self.at - 4, name, format!("{v} is negative")));
            }
        }
        let name = Sub(field, "codes");
        let length = self.count(name, 1)?;
        let start = self.at;
        let packed = self.take(length, name)?;
        let codes = unpack_codes(packed, controls, bits).map_err(|e| self.bad_at(start, name, e.to_string()))?;
        let [l0, l1, l2, span] = ranges;
        Ok((line, knots, Quantized { bits, low: [l0, l1, l2], span, codes }))
    }
}

impl Reader<'_> {
    /// Knot indices as [`Writer::knots`] writes them (deltas less `least`), at most `most`,
    /// each checked by `check` (given the knots before it and its index) before it is kept.
    fn knots(
        &mut self,
        field: &str,
        most: usize,
        least: u32,
        check: impl Fn(&[u32], u64) -> Result<(), KnotFault>,
    ) -> Result<Vec<u32>, ContainerError> {
        let name = Sub(field, "knot count");
        let start = self.at;
        // A Rice code takes a bit at least: the count is held to the bytes left, and to the
        // knots the curve can have, before anything is allocated for them.
        let count = self.count(name, 0)?;
        if count > most {
            return Err(self.bad_at(start, name, format!("{count} knots; its timeline has room for {most}")));
        }
        let left = self.bytes.len() - self.at;
        if count > 8 * left {
            return Err(self.bad_at(
                start,
                name,
                format!("{count} knots of a bit at least cannot fit in the {left} bytes left"),
            ));
        }
        if count == 0 {
            return Ok(Vec::new());
        }
        let name = Sub(field, "knot Rice parameter");
        let k = u32::from(self.u8(name)?);
        if k > MOST_RICE {
            return Err(self.bad_at(self.at - 1, name, format!("{k} is more than {MOST_RICE}")));
        }
        let start = self.at;
        let mut deltas = BitReader::new(&self.bytes[start..]);
        let mut knots: Vec<u32> = Vec::with_capacity(count);
        for i in 0..count {
            let field = || format!("{field} knot {i}");
            let end = || self.bad_at(start, field(), "the packed knots end before it".into());
            let (quotient, low) = deltas.rice(k).ok_or_else(end)?;
            // No delta reaches past every interior place: a longer run is named, not shifted.
            if quotient > (most as u64 + 1) >> k {
                return Err(self.bad_at(start, field(), format!("a delta's quotient {quotient} is past the timeline")));
            }
            let delta = (quotient << k | low) + u64::from(least);
            let at = u64::from(knots.last().copied().unwrap_or(0)) + delta;
            // The field's name made only for a message: one per knot was most of a load's time.
            check(&knots, at).map_err(|fault| self.bad_at(start, field(), fault.to_string()))?;
            knots.push(at as u32);
        }
        self.at = start + deltas.bytes_read();
        Ok(knots)
    }
}

/// Values packed low bit first.
#[derive(Default)]
struct BitWriter {
    bytes: Vec<u8>,
    pending: u64,
    filled: u32,
}

impl BitWriter {
    /// `value`'s low `bits` (at most 32).
    fn push(&mut self, value: u64, bits: u32) {
        self.pending |= (value & ((1u64 << bits) - 1)) << self.filled;
        self.filled += bits;
        while self.filled >= 8 {
            self.bytes.push(self.pending as u8);
            self.pending >>= 8;
            self.filled -= 8;
        }
    }

    /// `z` as a Rice code of parameter `k` ([`rice_bits`]).
    fn rice(&mut self, z: u64, k: u32) {
        let mut quotient = z >> k;
        while quotient > 0 {
            let run = quotient.min(32) as u32;
            self.push((1 << run) - 1, run);
            quotient -= u64::from(run);
        }
        self.push(0, 1);
        self.push(z, k);
    }

    fn finish(mut self) -> Vec<u8> {
        if self.filled > 0 {
            self.bytes.push(self.pending as u8);
        }
        self.bytes
    }
}

/// Values unpacked low bit first (the caller sized the slice), through a word of the next bits
/// kept in a register: a Rice code's length is known only once it is read, so each code waits
/// on the one before, and a load from memory at the bit position is no longer in that wait.
struct BitReader<'a> {
    bytes: &'a [u8],
    /// The first byte not yet in `word`.
    next: usize,
    /// The next bits, low first: `filled` of them (at most 63) counted; above them zeros or
    /// the bits that follow, which a refill writes again as they are.
    word: u64,
    filled: u32,
}

impl<'a> BitReader<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, next: 0, word: 0, filled: 0 }
    }

    /// Tops `word` up to 56 bits or more, or to the end of the bytes: the eight bytes from
    /// `next` in one read while there are eight, and the whole bytes of them that fit counted.
    #[inline(always)]
    fn refill(&mut self) {
        if let Some(eight) = self.bytes.get(self.next..self.next + 8) {
            self.word |= u64::from_le_bytes(eight.try_into().expect("eight bytes")) << self.filled;
            let whole = (63 - self.filled) / 8;
            self.next += whole as usize;
            self.filled += 8 * whole;
        } else {
            while self.filled <= 55 && self.next < self.bytes.len() {
                self.word |= u64::from(self.bytes[self.next]) << self.filled;
                self.next += 1;
                self.filled += 8;
            }
        }
    }

    /// Drops `n` (at most `filled`) counted bits.
    #[inline(always)]
    fn skip(&mut self, n: u32) {
        self.word = self.word.checked_shr(n).unwrap_or(0);
        self.filled -= n;
    }

    /// The next `bits` (at most 32), or `None` past the end.
    fn take(&mut self, bits: u32) -> Option<u64> {
        debug_assert!(bits <= 32);
        self.refill();
        if bits > self.filled {
            return None;
        }
        let v = self.word & ((1u64 << bits) - 1);
        self.skip(bits);
        Some(v)
    }

    /// A Rice code of parameter `k` (at most 31): its quotient and its low bits, or `None`
    /// when the input ends first. The caller bounds the quotient before joining the two.
    #[inline(always)]
    fn rice(&mut self, k: u32) -> Option<(u64, u64)> {
        self.refill();
        // Most codes lie within the counted bits: read from the word.
        let run = self.word.trailing_ones();
        if run + 1 + k <= self.filled {
            let low = (self.word >> (run + 1)) & ((1u64 << k) - 1);
            self.skip(run + 1 + k);
            return Some((u64::from(run), low));
        }
        let quotient = self.ones()?;
        Some((quotient, self.take(k)?))
    }

    /// The bytes the bits taken so far began in (a field packed to a byte ends there).
    fn bytes_read(&self) -> usize {
        (8 * self.next - self.filled as usize).div_ceil(8)
    }

    /// How many one bits come before the next zero bit, both taken (a Rice code's quotient),
    /// or `None` when the input ends first.
    fn ones(&mut self) -> Option<u64> {
        let mut count = 0;
        loop {
            self.refill();
            if self.filled == 0 {
                return None;
            }
            // Bits above the counted ones are not yet known: the run stops at `filled`.
            let run = self.word.trailing_ones().min(self.filled);
            if run < self.filled {
                self.skip(run + 1);
                return Some(count + u64::from(run));
            }
            count += u64::from(run);
            self.skip(run);
        }
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

    /// Values of every width 0..=32 read back as written, the last ones from the short word at
    /// the end of the bytes, and nothing past the end.
    #[test]
    fn bits_read_back_as_written_to_the_last_byte() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let values: Vec<(u64, u32)> = (0..500)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let bits = (i * 7 % 33) as u32;
                (state & ((1u64 << bits) - 1), bits)
            })
            .collect();
        let mut writer = BitWriter::default();
        values.iter().for_each(|&(v, bits)| writer.push(v, bits));
        let bytes = writer.finish();
        let mut reader = BitReader::new(&bytes);
        for (i, &(v, bits)) in values.iter().enumerate() {
            assert_eq!(reader.take(bits), Some(v), "value {i} of {bits} bits");
        }
        let left = 8 * bytes.len() - values.iter().map(|&(_, b)| b as usize).sum::<usize>();
        assert_eq!(reader.take(left as u32), Some(0), "the padding");
        assert_eq!(reader.take(1), None);
        // Unary runs across words: 0, 5, 40 and 70 ones, each ended by a zero; then the end.
        let mut writer = BitWriter::default();
        for run in [0u32, 5, 40, 70] {
            for _ in 0..run {
                writer.push(1, 1);
            }
            writer.push(0, 1);
        }
        writer.push(0b111, 3);
        let bytes = writer.finish();
        let mut reader = BitReader::new(&bytes);
        for run in [0, 5, 40, 70] {
            assert_eq!(reader.ones(), Some(run));
        }
        assert_eq!(reader.ones(), Some(3), "the padding's zeros end the last run");
        let all_ones = [0xffu8; 9];
        assert_eq!(BitReader::new(&all_ones).ones(), None, "no zero before the end");
        // Rice codes read as written, in the word and across its end, for every parameter.
        let values: Vec<(u64, u32)> =
            (0..400u64).map(|i| ((i * 2_654_435_761) % (1 << (i % 27)), (i % 32) as u32)).collect();
        let mut writer = BitWriter::default();
        values.iter().for_each(|&(z, k)| writer.rice(z, k));
        let bytes = writer.finish();
        let mut reader = BitReader::new(&bytes);
        for &(z, k) in &values {
            assert_eq!(reader.rice(k), Some((z >> k, z & ((1 << k) - 1))), "{z} at {k}");
        }
        // A code that fills the first word to its last bit (63 ones and the zero).
        let mut writer = BitWriter::default();
        writer.rice(63, 0);
        writer.push(0, 8);
        assert_eq!(BitReader::new(&writer.finish()).rice(0), Some((63, 0)));
    }

    #[test]
    fn codes_pack_as_residuals_and_unpack_to_the_same_codes_or_a_named_fault() {
        // A smooth ramp with a jump (a flip) in the middle, and the extremes of the width.
        let bits = 20;
        let top = (1u32 << bits) - 1;
        let mut codes: Vec<[u32; 3]> =
            (0..100u32).map(|i| [1000 + 37 * i, 500_000 - i * i, if i < 50 { 0 } else { top }]).collect();
        codes.push([top, 0, top]);
        let packed = pack_codes(&codes, bits);
        assert!(packed.len() * 8 < codes.len() * 3 * bits as usize / 2, "{} bytes: residuals are small", packed.len());
        assert_eq!(unpack_codes(&packed, codes.len(), bits).unwrap(), codes);
        assert_eq!(
            unpack_codes(&packed, codes.len(), 10).unwrap_err().to_string(),
            "control point 2 component 0 decodes to 1124, outside 10 bits"
        );
        // A run of one bits longer than any residual of the width: named, not shifted past 64.
        let mut runaway = BitWriter::default();
        runaway.push(0, 3 * 2);
        runaway.push(0, 3 * RICE_BITS);
        for _ in 0..40 {
            runaway.push(1, 1);
        }
        runaway.push(0, 8);
        assert_eq!(
            unpack_codes(&runaway.finish(), 2, 2).unwrap_err().to_string(),
            "control point 1 component 0: a residual's quotient 40 is larger than any of 2 bits"
        );
        assert_eq!(
            unpack_codes(&packed[..packed.len() - 2], codes.len(), bits).unwrap_err(),
            CodeFault::End(codes.len() - 1)
        );
    }

    #[test]
    fn a_knot_count_is_held_to_the_room_before_any_allocation_and_a_runaway_delta_is_named() {
        let mut out = Writer::default();
        out.count(1 << 40);
        out.u8(0);
        let mut r = Reader { bytes: &out.bytes, at: 0 };
        let e = r.knots("channel 0", 10, 0, |_, _| Ok(())).unwrap_err();
        assert_eq!(e.to_string(), "byte 0: channel 0 knot count: 1099511627776 knots; its timeline has room for 10");
        // Keys at 2, 3 and 9 of 10 (deltas less one: 1, 0, 5), read back and the bytes after.
        let mut out = Writer::default();
        out.knots(&[2, 3, 9], 1);
        out.u8(0xab);
        let mut r = Reader { bytes: &out.bytes, at: 0 };
        assert_eq!(r.knots("channel 0", 8, 1, |_, _| Ok(())).unwrap(), [2, 3, 9]);
        assert_eq!(r.u8("after").unwrap(), 0xab);
        // One knot whose delta's unary run is longer than the timeline.
        let mut out = Writer::default();
        out.count(1);
        out.u8(0);
        out.bytes(&[0xff, 0xff, 0x0f]);
        let mut r = Reader { bytes: &out.bytes, at: 0 };
        let e = r.knots("channel 0", 8, 0, |_, _| Ok(())).unwrap_err();
        assert_eq!(e.to_string(), "byte 2: channel 0 knot 0: a delta's quotient 20 is past the timeline");
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
            "byte 8: version: 9; this quatcurve reads version 5 (fit the source again)"
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
