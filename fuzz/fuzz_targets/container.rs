//! Fitted-container bytes (resealed) -> reader -> bake (fast CPU path) -> BVH and texture encoders, in
//! memory; and the runtime decoder at times before, across and after each clip.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quatcurve::formats::bvh;
use quatcurve::anim::loops::LoopMode;
use quatcurve::anim::curves::CurveChoice;
use quatcurve::bake;
use quatcurve::qcf::decoder::Decoder;
use quatcurve::qcf::Container;
use quatcurve::{Curve, CurveSpec, Device, DeviceChoice};

fuzz_target!(|bytes: &[u8]| {
    // The checksum made right again, so that the fuzzer's bytes reach the fields behind it.
    let mut bytes = bytes.to_vec();
    quatcurve::qcf::reseal(&mut bytes);
    if let Ok(decoder) = Decoder::from_bytes(&bytes) {
        for index in 0..decoder.clips().len() {
            let Ok(mut clip) = decoder.open(index) else { continue };
            let [start, end] = clip.span();
            let mut pose = vec![0.0; clip.pose_floats()];
            for i in -2..=14 {
                let _ = clip.pose(start + (end - start) * f64::from(i) / 12.0, &mut pose);
            }
        }
    }
    let Ok(container) = Container::from_bytes(&bytes) else { return };
    let animation = container.animation();
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
        if let Some(skeleton) = &container.bvh {
            let _ = bvh::skeleton(skeleton, &animation).map(|file| file.to_text(&animation.clips[0], &baked.frames()[0]));
        }
        if let Ok(order) = animation.parents_first() {
            let _ = bake::texture::sheets(&animation, &order, &baked, 0, bake::texture::TextureKind::Model, &device);
        }
    }
});
