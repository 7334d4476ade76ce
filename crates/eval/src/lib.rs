//! # quatcurve-eval
//!
//! Evaluation without a GPU: user [`track::Track`]s, the packed [`batch::Batch`] and its
//! builder (the only maker of one), sample times, the one [`job::EvalJob`] every device runs,
//! the rows it writes ([`output`]), the f64 reference (the oracle), the SIMD CPU path, and the
//! skeleton's maths (affine transforms, forward kinematics, skinning), and their files in and
//! out ([`io`]: track files, results, `.npy` arrays, written atomically; `arrays`, feature `npz`:
//! tracks from numpy arrays).
//!
//! The `quatcurve` crate re-exports these modules at its root (`quatcurve::batch`, ...) and
//! adds the GPU path and the one device value over all three.

#[cfg(feature = "npz")]
pub mod arrays;
pub mod batch;
pub mod cpu;
pub mod error;
pub mod euclidean;
pub mod io;
pub mod job;
pub mod options;
pub mod output;
pub mod reference;
pub mod sampling;
pub mod skeleton;
// Benchmark tracks for the CLI, the benches and tests; not part of the library's API.
#[doc(hidden)]
pub mod synthetic;
pub mod track;
