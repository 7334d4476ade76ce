//! A bounded, stable-Rust fuzz run of every parser (glTF/GLB, FBX, BVH, track JSON, .npy, fitted
//! containers, SMPL archives) and what
//! follows it: proptest mutates seed files (the real files in `../shared/data` when present,
//! and crafted ones) and each mutant goes through read, bake or evaluation (fast CPU path) and
//! the writers' encoders in memory. Accepted:
//! success or an input error (exit 2 in the CLI). Not accepted: a panic, an abort, a device
//! error. proptest shrinks a failure to a minimal mutation list; keep it as a hostile test.
//! The open-ended run is `cargo +nightly fuzz` (see `fuzz/`).

use super::{data_dir, tiny_gltf};
use crate::common::{f64_bytes, npy_bytes, npz_bytes};
use proptest::prelude::*;
use quatcurve::anim::curves::CurveChoice;
use quatcurve::anim::error::{InputError, InternalError};
use quatcurve::anim::loops::LoopMode;
use quatcurve::bake::error::BakeError;
use quatcurve::bake::{self};
use quatcurve::formats::{bvh, gltf};
use quatcurve::{Batch, Curve, CurveSpec, Device, DeviceChoice, SampleTimes, Sampling, TrackFile};
use std::path::Path;
use std::sync::OnceLock;

/// What a seed is, and so which reader it goes through.
#[derive(Clone, Copy, Debug)]
enum Kind {
    /// `.gltf` text or raw `.glb` bytes.
    Gltf,
    /// The JSON chunk of a GLB: mutated, then packed again with valid chunk lengths (so the
    /// mutants reach the glTF reader instead of failing the GLB header check).
    GlbJson,
    Bvh,
    Tracks,
    /// A `.npy` of rotations `[tracks, keys, 4]` (`eval --input`).
    Npy,
    /// A fitted container (`quatcurve fit`), resealed after the mutation ([`attempt`]).
    Container,
    /// An FBX file (read by ufbx).
    Fbx,
    /// An SMPL pose archive (`.npz`), mutated whole.
    Smpl,
    /// The `poses` array of an SMPL archive: mutated, then packed into an archive with a rate
    /// (so the mutants reach the array reader instead of failing the zip's checksums).
    SmplPoses,
}

struct Seed {
    name: &'static str,
    kind: Kind,
    bytes: Vec<u8>,
    /// The BIN chunk of a `GlbJson` seed.
    bin: Vec<u8>,
}

/// A two-joint BVH of three frames.
const TINY_BVH: &[u8] = b"HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation \
    Xrotation Yrotation\n JOINT Leg\n {\n  OFFSET 0 -1 0\n  CHANNELS 3 Zrotation Xrotation \
    Yrotation\n  End Site\n  {\n   OFFSET 0 -1 0\n  }\n }\n}\nMOTION\nFrames: 3\nFrame Time: 0.1\n0 \
    1 0 0 0 0 0 0 0\n0 1 0 10 5 0 20 0 0\n0 1 0 0 0 0 0 0 0\n";

fn seeds() -> &'static [Seed] {
    static SEEDS: OnceLock<Vec<Seed>> = OnceLock::new();
    SEEDS.get_or_init(|| {
        let q = [0.0, 0.0, 0.0, 1.0];
        let turn = [0.0, 0.382_683_43, 0.0, 0.923_879_5];
        let seed = |name, kind, bytes: Vec<u8>| Seed { name, kind, bytes, bin: Vec::new() };
        let mut seeds = vec![
            seed("tiny.gltf", Kind::Gltf, tiny_gltf(&[0.0, 0.5, 1.0], &[q, turn, q]).into_bytes()),
            seed("tiny.bvh", Kind::Bvh, TINY_BVH.to_vec()),
            seed(
                "demo.json",
                Kind::Tracks,
                serde_json::to_vec(&TrackFile { tracks: quatcurve::io::demo_tracks() }).unwrap(),
            ),
            seed("walk.npy", Kind::Npy, {
                let header = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4), }";
                let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
                bytes.extend(((header.len() + 1) as u16).to_le_bytes());
                bytes.extend(header.as_bytes());
                bytes.push(b'\n');
                bytes.extend(
                    [0.0f32, 0.0, 0.0, 1.0, 0.1, 0.0, 0.0, 0.995, 0.2, 0.0, 0.0, 0.98]
                        .repeat(2)
                        .iter()
                        .flat_map(|v| v.to_le_bytes()),
                );
                bytes
            }),
        ];
        let poses = smpl_poses();
        seeds.push(seed("smpl.npz", Kind::Smpl, smpl_archive(poses.clone())));
        seeds.push(seed("smpl poses.npy", Kind::SmplPoses, poses));
        let fitted = fitted_container(std::str::from_utf8(TINY_BVH).unwrap());
        seeds.push(seed("tiny.qcf", Kind::Container, fitted));
        if let Some(data) = data_dir() {
            let fox = std::fs::read(data.join("Fox.glb")).unwrap();
            let glb = ::gltf::binary::Glb::from_slice(&fox).unwrap();
            seeds.push(Seed {
                name: "Fox.glb json",
                kind: Kind::GlbJson,
                bytes: glb.json.to_vec(),
                bin: glb.bin.unwrap().to_vec(),
            });
            seeds.push(seed("Fox.glb", Kind::Gltf, fox));
            seeds.push(seed("CesiumMan.fbx", Kind::Fbx, std::fs::read(data.join("CesiumMan.fbx")).unwrap()));
            seeds.push(seed("SimpleSkin.gltf", Kind::Gltf, std::fs::read(data.join("SimpleSkin.gltf")).unwrap()));
            // The first 40 frames of a CMU clip (all 31 joints), for speed.
            let text = std::fs::read_to_string(data.join("cmu_131_01.bvh")).unwrap();
            let (head, motion) = text.split_at(text.find("MOTION").unwrap());
            let lines: Vec<&str> = motion.lines().collect();
            let frames = lines[3..43].join("\n");
            seeds.push(seed(
                "cmu_131_01.bvh head",
                Kind::Bvh,
                format!("{head}MOTION\nFrames: 40\n{}\n{frames}\n", lines[2]).into_bytes(),
            ));
        }
        seeds
    })
}

/// SMPL's `poses` `[4, 72]` as a `.npy`: every joint turning a little each frame.
fn smpl_poses() -> Vec<u8> {
    let values: Vec<f64> = (0..4 * 72).map(|i| 0.01 * (i % 72) as f64 * (i / 72) as f64).collect();
    npy_bytes("<f8", &[4, 72], &f64_bytes(&values))
}

/// An SMPL archive of `poses` at 30 Hz.
fn smpl_archive(poses: Vec<u8>) -> Vec<u8> {
    npz_bytes(&[("poses", poses), ("mocap_framerate", npy_bytes("<f8", &[], &f64_bytes(&[30.0])))])
}

/// The container `quatcurve fit` writes for a BVH text (1 cm units).
fn fitted_container(text: &str) -> Vec<u8> {
    use quatcurve::fit::clip::{fit_clip, Budget};
    use quatcurve::qcf::{BvhSkeleton, Container};
    let file = bvh::parse(text).unwrap();
    let animation = file.animation("clip");
    let budget = Budget { max_error: 0.01, between_error: 0.3, vertex_distance: 3.0 };
    let clip = fit_clip(&animation, 0, &budget).unwrap().clip;
    let bvh = BvhSkeleton { hierarchy: file.hierarchy().to_string(), frame_time: file.frame_time };
    Container { joints: animation.joints, bvh: Some(bvh), clips: vec![clip] }.to_bytes()
}

/// One edit of a seed's bytes.
#[derive(Clone, Debug)]
enum Mutation {
    FlipBit {
        at: usize,
        bit: u8,
    },
    SetByte {
        at: usize,
        value: u8,
    },
    Delete {
        at: usize,
        len: usize,
    },
    Insert {
        at: usize,
        token: &'static str,
    },
    /// Replace the `nth` run of ASCII digits (counts, offsets, indices, key values) by `token`.
    ReplaceNumber {
        nth: usize,
        token: &'static str,
    },
}

const BYTES: &[u8] = b"\x00\xff\x7f\x80-.e\"{}[],: 09";
const TOKENS: &[&str] = &[
    "-1",
    "0",
    "4294967295",
    "18446744073709551615",
    "1e308",
    "-1e308",
    "NaN",
    "inf",
    "1e-320",
    "99999999999",
    "2",
    "\"",
    ",",
    "}",
    "]",
    "null",
];

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 0u8..8).prop_map(|(at, bit)| Mutation::FlipBit { at, bit }),
        (any::<usize>(), prop::sample::select(BYTES)).prop_map(|(at, value)| Mutation::SetByte { at, value }),
        (any::<usize>(), 1usize..16).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (any::<usize>(), prop::sample::select(TOKENS)).prop_map(|(at, token)| Mutation::Insert { at, token }),
        (any::<usize>(), prop::sample::select(TOKENS)).prop_map(|(nth, token)| Mutation::ReplaceNumber { nth, token }),
        (any::<usize>(), prop::sample::select(TOKENS)).prop_map(|(nth, token)| Mutation::ReplaceNumber { nth, token }),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    if bytes.is_empty() {
        return;
    }
    match *m {
        Mutation::FlipBit { at, bit } => {
            let at = at % bytes.len();
            bytes[at] ^= 1 << bit;
        }
        Mutation::SetByte { at, value } => {
            let at = at % bytes.len();
            bytes[at] = value;
        }
        Mutation::Delete { at, len } => {
            let at = at % bytes.len();
            bytes.drain(at..(at + len).min(bytes.len()));
        }
        Mutation::Insert { at, token } => {
            let at = at % (bytes.len() + 1);
            bytes.splice(at..at, token.bytes());
        }
        Mutation::ReplaceNumber { nth, token } => {
            let mut runs = Vec::new();
            let mut i = 0;
            while i < bytes.len() {
                if bytes[i].is_ascii_digit() {
                    let start = i;
                    while i < bytes.len() && bytes[i].is_ascii_digit() {
                        i += 1;
                    }
                    runs.push(start..i);
                } else {
                    i += 1;
                }
            }
            if !runs.is_empty() {
                let range = runs[nth % runs.len()].clone();
                bytes.splice(range, token.bytes());
            }
        }
    }
}

fn device() -> &'static Device {
    static DEVICE: OnceLock<Device> = OnceLock::new();
    DEVICE.get_or_init(|| Device::open(DeviceChoice::Cpu).unwrap())
}

/// How far one file got through read, bake and the encoders.
#[derive(Debug, PartialEq)]
enum Reached {
    /// Not a file of its kind at all (not UTF-8, not track JSON), or nothing in it to bake.
    Skipped(&'static str),
    /// Baked or evaluated: this many samples.
    Baked(usize),
}

/// Reads, bakes and encodes `bytes` as `seed`'s kind of file.
fn attempt(seed: &Seed, bytes: &[u8]) -> Result<Reached, BakeError> {
    let spec = CurveChoice::Family(CurveSpec::new(Curve::BSplineInterp));
    match seed.kind {
        Kind::Gltf | Kind::GlbJson => {
            let packed;
            let bytes = if let Kind::GlbJson = seed.kind {
                let glb = ::gltf::binary::Glb {
                    header: ::gltf::binary::Header { magic: *b"glTF", version: 2, length: 0 },
                    json: bytes.into(),
                    bin: Some(seed.bin.as_slice().into()),
                };
                packed = glb.to_vec().map_err(|e| {
                    InputError::from(InternalError::Encode { what: "the mutated GLB".into(), error: e.into() })
                })?;
                &packed[..]
            } else {
                bytes
            };
            // An empty directory: relative URIs find nothing (the URI tests cover them).
            let file = gltf::from_bytes(bytes, Path::new("/nonexistent-quatcurve-dir"), gltf::UriPolicy::default())?;
            if file.animation.clips.is_empty() {
                return Ok(Reached::Skipped("no clip"));
            }
            let baked = bake::bake(&file.animation, &spec, bake::ClipRate::Fit(10.0), LoopMode::Auto, device())?;
            file.to_glb(&baked.frames())?;
            let order = file.animation.parents_first()?;
            for clip in 0..baked.clips.len() {
                let _ = bake::texture::sheets(
                    &file.animation,
                    &order,
                    &baked,
                    clip,
                    bake::texture::TextureKind::Skin,
                    device(),
                );
            }
            Ok(Reached::Baked(baked.sample_count()))
        }
        Kind::Bvh => {
            let Ok(text) = std::str::from_utf8(bytes) else { return Ok(Reached::Skipped("not UTF-8")) };
            let file = bvh::parse(text)?;
            let animation = file.animation("clip");
            if animation.clips.is_empty() {
                return Ok(Reached::Skipped("no clip"));
            }
            let baked = bake::bake(&animation, &spec, bake::ClipRate::Fit(10.0), LoopMode::Auto, device())?;
            let _ = file.to_text(&animation.clips[0], &baked.frames()[0]);
            let order = animation.parents_first()?;
            let _ = bake::texture::sheets(&animation, &order, &baked, 0, bake::texture::TextureKind::Model, device());
            Ok(Reached::Baked(baked.sample_count()))
        }
        Kind::Container => {
            // Its checksum made right again, so that the mutant reaches the fields behind it
            // (the checksum's own refusals are the container's unit tests').
            let mut bytes = bytes.to_vec();
            quatcurve::qcf::reseal(&mut bytes);
            let container = quatcurve::qcf::Container::from_bytes(&bytes).map_err(InputError::from)?;
            let animation = container.animation();
            if animation.clips.is_empty() {
                return Ok(Reached::Skipped("no clip"));
            }
            let baked = bake::bake(&animation, &spec, bake::ClipRate::Fit(10.0), LoopMode::Auto, device())?;
            if let Some(skeleton) = &container.bvh {
                let _ = bvh::skeleton(skeleton, &animation)
                    .map(|file| file.to_text(&animation.clips[0], &baked.frames()[0]));
            }
            let order = animation.parents_first()?;
            let _ = bake::texture::sheets(&animation, &order, &baked, 0, bake::texture::TextureKind::Model, device());
            Ok(Reached::Baked(baked.sample_count()))
        }
        Kind::Fbx => {
            let file = quatcurve::formats::fbx::from_bytes(bytes)?.gltf;
            if file.animation.clips.is_empty() {
                return Ok(Reached::Skipped("no clip"));
            }
            let baked = bake::bake(&file.animation, &spec, bake::ClipRate::Fit(10.0), LoopMode::Auto, device())?;
            file.to_glb(&baked.frames())?;
            let order = file.animation.parents_first()?;
            let kind = bake::texture::TextureKind::Skin;
            let _ = bake::texture::sheets(&file.animation, &order, &baked, 0, kind, device());
            Ok(Reached::Baked(baked.sample_count()))
        }
        Kind::Smpl | Kind::SmplPoses => {
            let packed;
            let bytes = if let Kind::SmplPoses = seed.kind {
                packed = smpl_archive(bytes.to_vec());
                &packed[..]
            } else {
                bytes
            };
            let file = quatcurve::formats::smpl::from_bytes(bytes)?;
            let animation = file.animation("clip");
            let spec = CurveChoice::Family(CurveSpec::new(Curve::Slerp));
            let baked = bake::bake(&animation, &spec, bake::ClipRate::Fit(10.0), LoopMode::Auto, device())?;
            file.to_npz(&baked.frames()[0], false)?;
            file.to_npz(&baked.frames()[0], true)?;
            Ok(Reached::Baked(baked.sample_count()))
        }
        Kind::Npy => {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("tracks.npy");
            std::fs::write(&path, bytes).unwrap();
            let Ok(tracks) = quatcurve::arrays::read_tracks(&path, Some(30.0)) else {
                return Ok(Reached::Skipped("not a track array"));
            };
            let batch = Batch::from_tracks(&tracks, &spec.spec())?;
            let times = SampleTimes::uniform(&batch, Sampling::Count(5))?;
            let job = quatcurve::EvalJob::new(&batch, &times).layout(quatcurve::Layout::Track).derivatives(true);
            device().evaluate(&job)?;
            Ok(Reached::Baked(times.total()))
        }
        Kind::Tracks => {
            let Ok(file) = serde_json::from_slice::<TrackFile>(bytes) else {
                return Ok(Reached::Skipped("not track JSON"));
            };
            // Every curve is tried (a mutant one curve refuses may reach another's kernel); the
            // first refusal is the outcome, a device failure at once.
            let (mut samples, mut refused) = (0, None);
            for curve in [Curve::BSplineInterp, Curve::Squad, Curve::Hermite] {
                let evaluated = (|| -> Result<usize, BakeError> {
                    let batch = Batch::from_tracks(&file.tracks, &CurveSpec::new(curve))?;
                    let overrides: Vec<Option<&[f64]>> =
                        file.tracks.iter().map(|t| t.sample_times.as_deref()).collect();
                    let times = SampleTimes::new(&batch, &overrides, Sampling::Count(5))?;
                    let job =
                        quatcurve::EvalJob::new(&batch, &times).layout(quatcurve::Layout::Track).derivatives(true);
                    device().evaluate(&job)?;
                    Ok(times.total())
                })();
                match evaluated {
                    Ok(n) => samples += n,
                    Err(e) if e.is_internal_failure() => return Err(e),
                    Err(e) => refused = refused.or(Some(e)),
                }
            }
            refused.map_or(Ok(Reached::Baked(samples)), Err)
        }
    }
}

/// [`attempt`], where every failure must be the input's (named, exit code 2), never the
/// device's or ours.
fn run(seed: &Seed, bytes: &[u8]) -> Result<(), String> {
    match attempt(seed, bytes) {
        Err(e) if e.is_internal_failure() => Err(format!("{}: a device error from file contents: {e}", seed.name)),
        _ => Ok(()),
    }
}

/// The seeds themselves are read and baked without any error (so the mutants start from files
/// that reach the bake and the encoders, not from ones the reader already refuses).
#[test]
fn every_seed_bakes() {
    for seed in seeds() {
        match attempt(seed, &seed.bytes) {
            Ok(Reached::Baked(samples)) if samples > 0 => {}
            other => panic!("{}: {other:?}", seed.name),
        }
    }
}

proptest! {
    // Deterministic (a fixed seed per run of the suite would hide nothing new; proptest's
    // default random seed explores new mutants each CI run, and prints the failing one).
    #![proptest_config(ProptestConfig { cases: 8_000, failure_persistence: None, ..ProptestConfig::default() })]
    #[test]
    fn mutated_files_are_read_or_refused_never_crash(pick in any::<usize>(), mutations in prop::collection::vec(mutation(), 1..6)) {
        let seeds = seeds();
        let seed = &seeds[pick % seeds.len()];
        let mut bytes = seed.bytes.clone();
        for m in &mutations {
            apply(&mut bytes, m);
        }
        prop_assert_eq!(run(seed, &bytes), Ok(()));
    }
}
