//! glTF/GLB bytes -> reader -> bake (fast CPU path) -> GLB and texture encoders, in memory.
//! Errors are fine; a panic or an abort is a finding.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quatcurve::formats::gltf;
use quatcurve::anim::loops::LoopMode;
use quatcurve::anim::curves::CurveChoice;
use quatcurve::bake;
use quatcurve::{Curve, CurveSpec, Device, DeviceChoice};
use std::path::Path;

fuzz_target!(|bytes: &[u8]| {
    let Ok(file) = gltf::from_bytes(bytes, Path::new("/nonexistent-quatcurve-dir"), gltf::UriPolicy::default()) else {
        return;
    };
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    if let Ok(baked) = bake::bake(
        &file.animation,
        &CurveChoice::Family(CurveSpec::new(Curve::BSplineInterp)),
        bake::ClipRate::Fit(10.0),
        LoopMode::Auto,
        &device,
    ) {
        let _ = file.to_glb(&baked.frames());
        let Ok(order) = file.animation.parents_first() else { return };
        for clip in 0..baked.clips.len() {
            let _ =
                bake::texture::sheets(&file.animation, &order, &baked, clip, bake::texture::TextureKind::Skin, &device);
        }
    }
});
