//! # quatcurve
//!
//! Smooth rotation curves for huge batches of animation tracks.
//!
//! The core is Kim, Kim & Shin's cumulative form (SIGGRAPH 1995):
//! `q(t) = q_0 prod_i exp(w_i B~_i(t))` with `w_i = log(q_{i-1}^-1 q_i)`, which turns any
//! Euclidean spline basis into a unit-quaternion curve with the same continuity, local control
//! and closed-form derivatives. quatcurve evaluates slerp, squad, KKS Bezier, KKS Hermite,
//! Nam-Kim great-arc blends, order-k KKS B-splines and the C2 cubic B-spline through every
//! key ([`interp`]), open or looping (`CurveSpec::looping`).
//!
//! Flow: user [`Track`]s -> [`BatchBuilder`] (validation, hemisphere alignment, coefficients,
//! knots: done once, in f64) -> packed [`Batch`] -> an [`EvalJob`] (with `validate()`) that
//! every device runs -> [`Output`] (f64) or [`FloatOutput`] rows. Conventions (quaternion order `x, y, z, w`, half-angle exp/log, body-frame
//! derivatives) are those of the project's design document, `docs/DESIGN.md` (cited as
//! "DESIGN section N" throughout), summarized in the README.
//!
//! ```
//! use quatcurve::{Batch, Curve, CurveSpec, Device, DeviceChoice, EvalJob, SampleTimes, Sampling, Track};
//!
//! // Two tracks of three keys (x, y, z, w) at times 0, 0.5 and 1 s.
//! let quarter = [0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2];
//! let keys = vec![[0.0, 0.0, 0.0, 1.0], quarter, [0.0, 0.0, 1.0, 0.0]];
//! let tracks: Vec<Track> = (0..2)
//!     .map(|_| Track { times: Some(vec![0.0, 0.5, 1.0]), ..Track::from_rotations(keys.clone()) })
//!     .collect();
//! // C2 through every key; built once (validated, solved, packed).
//! let batch = Batch::from_tracks(&tracks, &CurveSpec::new(Curve::BSplineInterp))?;
//! let times = SampleTimes::uniform(&batch, Sampling::Rate(60.0))?;
//! // Any device: a hardware GPU when there is one, else the fast CPU path.
//! let device = Device::open(DeviceChoice::Auto)?;
//! let out = device.evaluate(&EvalJob::new(&batch, &times).derivatives(true))?;
//! assert_eq!(out.rotations.len(), 2 * 61);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

// The workspace's crates at one root, so users see one library: the maths (quatcurve-core, no
// I/O), evaluation without a GPU (quatcurve-eval), the WGSL programs and their translations
// (quatcurve-shader), the GPU path (quatcurve-gpu), the device
// over them (quatcurve-device), the animation model (quatcurve-anim), the fitted container
// (quatcurve-qcf), the formats (quatcurve-formats), jobs over files (quatcurve-files), and
// the products: analysis, the bake, the fit, the viewer.
pub use quatcurve_analysis as analysis;
pub use quatcurve_anim as anim;
pub use quatcurve_bake as bake;
pub use quatcurve_core::{curve, interp, isa, quat, real};
pub use quatcurve_device as device;
#[doc(hidden)]
pub use quatcurve_eval::synthetic;
pub use quatcurve_eval::{
    arrays, batch, cpu, error, euclidean, io, job, options, output, reference, sampling, skeleton, track,
};
pub use quatcurve_files as files;
pub use quatcurve_fit as fit;
pub use quatcurve_formats as formats;
#[cfg(feature = "gpu")]
pub use quatcurve_gpu as gpu;
pub use quatcurve_play as play;
pub use quatcurve_qcf as qcf;
pub use quatcurve_shader as shader;
// Charts serve the CLI; they are not part of the library's API.
#[cfg(feature = "plot")]
#[doc(hidden)]
pub use quatcurve_plot as plot;
#[cfg(feature = "view")]
pub use quatcurve_view as view;

pub use batch::{Batch, BatchBuilder, PackedTrack, TrackView};
pub use cpu::CpuEvaluator;
pub use device::{Device, DeviceChoice, DeviceError, EvalOutput};
pub use error::{Error, Result, TrackId};
#[cfg(feature = "gpu")]
pub use gpu::GpuDevice;
pub use job::{EvalJob, JobOptions};
pub use output::{FloatOutput, Layout, Output, Row};
pub use quatcurve_core::curve::{Blend, Curve, CurveSpec, KnotMode, Tangents, DEFAULT_CURVE};
pub use quatcurve_core::quat::{QuatF64, Quaternion, Vec3F64, Vector3};
pub use reference::{evaluate, Sample};
pub use sampling::{SampleTimes, Sampling, DEFAULT_RATE};
pub use track::{Track, TrackFile};
