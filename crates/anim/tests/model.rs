//! The animation model through its own API: a hierarchy's order and its refusals, whether a
//! clip loops, each refusal a typed `AnimationError` naming the joint, clip or channel.

use quatcurve_anim::curves::CurveChoice;
use quatcurve_anim::error::{AnimationError, InputError};
use quatcurve_anim::loops::{clip_loops, LoopMode};
use quatcurve_anim::{Animation, Channel, Clip, Joint, Property};
use quatcurve_core::curve::{Curve, CurveSpec};

/// A chain root -> arm -> hand, its clip turning the arm by `end` radians about z from rest.
fn arm(end: f64) -> Animation {
    let joints = vec![
        Joint::at("root".into(), None, [0.0; 3]),
        Joint::at("arm".into(), Some(0), [0.0, 1.0, 0.0]),
        Joint::at("hand".into(), Some(1), [0.0, 1.0, 0.0]),
    ];
    let about_z = |a: f64| [0.0, 0.0, (a / 2.0).sin(), (a / 2.0).cos()];
    let turn =
        Channel::keys(1, Property::Rotation, vec![0.0, 0.5, 1.0], vec![about_z(0.0), about_z(1.0), about_z(end)]);
    Animation { joints, clips: vec![Clip { name: "wave".into(), channels: vec![turn] }], skins: Vec::new() }
}

#[test]
fn parents_come_before_their_children_whatever_the_joints_order() {
    let mut animation = arm(0.0);
    // The hand first, its parent last.
    animation.joints.swap(0, 2);
    animation.joints[0].parent = Some(1);
    animation.joints[1].parent = Some(2);
    animation.joints[2].parent = None;
    assert_eq!(animation.parents_first().unwrap(), [2, 1, 0]);
}

#[test]
fn a_hierarchy_with_a_cycle_is_refused_naming_a_joint_on_it() {
    let mut animation = arm(0.0);
    animation.joints[0].parent = Some(2);
    match animation.parents_first() {
        Err(AnimationError::Cycle { name, .. }) => assert!(["root", "arm", "hand"].contains(&name.as_str()), "{name}"),
        other => panic!("expected a cycle, got {other:?}"),
    }
}

#[test]
fn a_parent_past_the_joints_is_refused_naming_both() {
    let mut animation = arm(0.0);
    animation.joints[2].parent = Some(7);
    let refused = animation.parents_first().unwrap_err();
    assert_eq!(refused, AnimationError::MissingParent { joint: 2, name: "hand".into(), parent: 7 });
}

#[test]
fn a_clip_that_ends_where_it_starts_loops_by_itself() {
    let animation = arm(0.0);
    let clip = &animation.clips[0];
    assert!(clip_loops(&animation, clip, &CurveChoice::Source, LoopMode::Auto).unwrap());
    assert!(!clip_loops(&animation, clip, &CurveChoice::Source, LoopMode::Off).unwrap());
}

#[test]
fn an_open_clip_does_not_loop_by_itself_and_is_refused_as_a_loop_naming_its_channel() {
    let animation = arm(0.5);
    let clip = &animation.clips[0];
    assert!(!clip_loops(&animation, clip, &CurveChoice::Source, LoopMode::Auto).unwrap());
    match clip_loops(&animation, clip, &CurveChoice::Source, LoopMode::On) {
        Err(InputError::Animation(AnimationError::LoopOpen { channel, angle, .. })) => {
            assert_eq!(channel, "clip 'wave', arm rotation");
            assert!((angle - 0.5).abs() < 1e-12, "{angle}");
        }
        other => panic!("expected the loop refused, got {other:?}"),
    }
}

#[test]
fn a_curve_that_cannot_loop_is_refused_as_a_loop_naming_those_that_can() {
    let animation = arm(0.0);
    let bezier = CurveChoice::Family(CurveSpec::new(Curve::Bezier));
    match clip_loops(&animation, &animation.clips[0], &bezier, LoopMode::On) {
        Err(InputError::Animation(AnimationError::CurveDoesNotLoop { clip, looping, .. })) => {
            assert_eq!(clip, "wave");
            assert!(!looping.is_empty());
        }
        other => panic!("expected the curve refused, got {other:?}"),
    }
}
