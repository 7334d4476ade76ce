//! Tests of the f64 reference evaluator against the mathematics.

mod analysis;
mod bspline;
mod euclidean;
mod families;
mod hermite;
mod interp;
mod nam_kim;
mod single_axis;
mod squad_slerp;
mod validation;
