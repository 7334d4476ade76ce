//! Playback through its own API ([`Playback`]): every instance's palette on the fast CPU path
//! held to the f64 reference, and the rules a `Playback` checks when it is built.

use quatcurve_anim::curves::CurveChoice;
use quatcurve_anim::error::{AnimationError, InputError};
use quatcurve_anim::loops::LoopMode;
use quatcurve_device::{Device, DeviceChoice};
use quatcurve_play::{ClipTime, Instance, Playback};

fn crowd() -> quatcurve_anim::Animation {
    quatcurve_formats::crowd::crowd(1)
}

#[test]
fn palettes_on_the_cpu_path_are_the_reference_s_within_f32_rounding() {
    let playback = Playback::new(crowd(), &CurveChoice::Source, LoopMode::Auto, None).unwrap();
    let instances: Vec<Instance> = (0..16)
        .map(|i| Instance {
            first: ClipTime { clip: 0, time: 0.37 * f64::from(i) },
            second: (i % 3 == 0).then_some((ClipTime { clip: 0, time: 1.0 + 0.1 * f64::from(i) }, 0.25)),
        })
        .collect();
    let fast = playback.palettes(&Device::open(DeviceChoice::Cpu).unwrap(), &instances).unwrap();
    let oracle = playback.palettes(&Device::open(DeviceChoice::Reference).unwrap(), &instances).unwrap();
    assert_eq!(fast.len(), oracle.len());
    assert!(!fast.is_empty());
    let worst = fast.iter().zip(&oracle).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    // Palettes hold rotations (unit) and translations of a rig about 2 units tall.
    assert!(worst < 2e-4, "largest difference {worst}");
}

#[test]
fn a_skin_the_animation_does_not_have_is_refused_naming_the_count() {
    let error = Playback::new(crowd(), &CurveChoice::Source, LoopMode::Auto, Some(3)).unwrap_err();
    let skins = crowd().skins.len();
    match error {
        InputError::Animation(AnimationError::NoSuchSkin { skin: 3, skins: s }) if s == skins => {}
        other => panic!("expected skin 3 of {skins} refused, got {other:?}"),
    }
}
