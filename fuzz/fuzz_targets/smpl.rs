//! SMPL pose archive bytes (`.npz`) -> reader -> bake (fast CPU path) -> the archive written
//! back, in memory.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quatcurve::formats::smpl;
use quatcurve::anim::loops::LoopMode;
use quatcurve::anim::curves::CurveChoice;
use quatcurve::bake;
use quatcurve::{Curve, CurveSpec, Device, DeviceChoice};

fuzz_target!(|bytes: &[u8]| {
    let Ok(file) = smpl::from_bytes(bytes) else { return };
    let animation = file.animation("clip");
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    if let Ok(baked) =
        bake::bake(&animation, &CurveChoice::Family(CurveSpec::new(Curve::Slerp)), bake::ClipRate::Fit(10.0), LoopMode::Auto, &device)
    {
        let _ = file.to_npz(&baked.frames()[0], false);
    }
});
