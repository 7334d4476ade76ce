//! BVH text -> parser -> bake (fast CPU path) -> BVH and texture encoders, in memory.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quatcurve::formats::bvh;
use quatcurve::anim::loops::LoopMode;
use quatcurve::anim::curves::CurveChoice;
use quatcurve::bake;
use quatcurve::{Curve, CurveSpec, Device, DeviceChoice};

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    let Ok(file) = bvh::parse(text) else { return };
    let animation = file.animation("clip");
    if animation.clips.is_empty() {
        return;
    }
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    if let Ok(baked) = bake::bake(
        &animation,
        &CurveChoice::Family(CurveSpec::new(Curve::BSplineInterp)),
        bake::ClipRate::Fit(10.0),
        LoopMode::Auto,
        &device,
    ) {
        let _ = file.to_text(&animation.clips[0], &baked.frames()[0]);
        if let Ok(order) = animation.parents_first() {
            let _ = bake::texture::sheets(&animation, &order, &baked, 0, bake::texture::TextureKind::Model, &device);
        }
    }
});
