//! FBX bytes -> ufbx's reader and the glTF it converts to -> bake (fast CPU path) -> the baked GLB
//! and skin texture rows, in memory.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quatcurve::formats::fbx;
use quatcurve::anim::loops::LoopMode;
use quatcurve::anim::curves::CurveChoice;
use quatcurve::bake;
use quatcurve::{Curve, CurveSpec, Device, DeviceChoice};

fuzz_target!(|bytes: &[u8]| {
    let Ok(file) = fbx::from_bytes(bytes) else { return };
    let file = file.gltf;
    if file.animation.clips.is_empty() {
        return;
    }
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    let spec = CurveChoice::Family(CurveSpec::new(Curve::BSplineInterp));
    if let Ok(baked) = bake::bake(&file.animation, &spec, bake::ClipRate::Fit(10.0), LoopMode::Auto, &device) {
        let _ = file.to_glb(&baked.frames());
        if let Ok(order) = file.animation.parents_first() {
            let _ = bake::texture::sheets(&file.animation, &order, &baked, 0, bake::texture::TextureKind::Skin, &device);
        }
    }
});
