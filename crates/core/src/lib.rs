//! # quatcurve-core
//!
//! The mathematics every quatcurve path shares, with no I/O: reals and second-order jets
//! ([`real`]), quaternions with the papers' half-angle exp and log ([`quat`]), the cumulative
//! bases ([`basis`]), span lookup and loop wrap ([`segment`]), the curve families and their
//! names ([`curve`]), and the C2 interpolation solve ([`interp`]). The SIMD instruction set
//! the lane types run is chosen at run time ([`isa`]).
//!
//! The `quatcurve` crate re-exports these modules; depend on it unless only the maths is wanted.

pub mod basis;
pub mod curve;
pub mod interp;
pub mod isa;
pub mod quat;
pub mod real;
pub mod segment;
