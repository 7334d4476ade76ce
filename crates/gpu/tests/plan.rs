//! The GPU crate through its own API, without an adapter: what a host uploads for resident
//! playback (`ResidentCurves`, the plan `CurvePalettes` runs and the viewer's page mirrors), and
//! the typed refusals of work that does not fit.

use quatcurve_eval::skeleton::{PoseCurves, PoseSource, PoseTimes, POSE_PROPERTIES};
use quatcurve_gpu::error::{GpuError, JobError};
use quatcurve_gpu::layout::grid;
use quatcurve_gpu::playback::{FrameBuffer, ResidentCurves};

/// Two joints, a root and its child one unit up, posed by constants in each of `clips` clips.
fn still(clips: usize) -> (Vec<PoseSource>, [Option<usize>; 2], [usize; 2]) {
    let rest = |translation: [f32; 4]| {
        [
            PoseSource::Value([0.0, 0.0, 0.0, 1.0]),
            PoseSource::Value(translation),
            PoseSource::Value([1.0, 1.0, 1.0, 0.0]),
        ]
    };
    let clip = [rest([0.0; 4]), rest([0.0, 1.0, 0.0, 0.0])].concat();
    (clip.repeat(clips), [None, Some(0)], [0, 1])
}

fn curves<'a>(sources: Vec<PoseSource>, parents: &'a [Option<usize>], order: &'a [usize]) -> PoseCurves<'a> {
    PoseCurves { batch: None, vectors: Vec::new(), sources, parents, order, skin: None }
}

#[test]
fn a_plan_sizes_each_frame_buffer_by_its_joints_and_counts_the_clips() {
    let (sources, parents, order) = still(3);
    let plan = ResidentCurves::new(&curves(sources, &parents, &order), 1 << 20).unwrap();
    assert_eq!((plan.joints, plan.clips, plan.skin_joints), (2, 3, 2));
    assert_eq!(plan.frame_floats(FrameBuffer::Local), 2 * quatcurve_eval::output::LOCAL_CHANNELS);
    assert_eq!(plan.frame_floats(FrameBuffer::Model), 2 * quatcurve_eval::output::MATRIX_CHANNELS);
    assert!(plan.buffers.iter().any(|b| b.name == "fk_parents"), "the hierarchy is uploaded");
}

#[test]
fn sources_that_are_not_whole_clips_are_refused_with_their_count() {
    let (mut sources, parents, order) = still(1);
    sources.pop();
    match ResidentCurves::new(&curves(sources, &parents, &order), 1 << 20) {
        Err(GpuError::Job(JobError::NotWhole { what: "sources", len, .. })) => assert_eq!(len, 2 * POSE_PROPERTIES - 1),
        other => panic!("expected the sources refused, got {other:?}"),
    }
}

#[test]
fn an_instance_in_a_clip_the_plan_lacks_is_refused_naming_it() {
    let (sources, parents, order) = still(2);
    let plan = ResidentCurves::new(&curves(sources, &parents, &order), 1 << 20).unwrap();
    let fine = PoseTimes { clips: [0, 1], times: [0.0, 0.5], weight: 0.25 };
    assert_eq!(plan.records(&[fine]).unwrap().len(), 1);
    let past = PoseTimes { clips: [0, 2], ..fine };
    match plan.records(&[fine, past]) {
        Err(GpuError::Job(JobError::Instance { instance: 1, clips: [0, 2], .. })) => {}
        other => panic!("expected instance 1 refused, got {other:?}"),
    }
    let heavy = PoseTimes { weight: 1.5, ..fine };
    assert!(matches!(plan.records(&[heavy]), Err(GpuError::Job(JobError::Instance { instance: 0, .. }))));
}

#[test]
fn more_workgroups_than_a_2d_dispatch_holds_are_refused() {
    assert_eq!(grid(10, 4).unwrap(), [4, 3]);
    assert!(matches!(grid(17, 4), Err(GpuError::Job(JobError::Workgroups(17)))));
}
