//! `quatcurve bake` (placeholder while being written).
use super::Failure;
use clap::Args;
#[derive(Args, Debug)]
pub struct BakeArgs {}
pub fn run(_: &BakeArgs) -> Result<(), Failure> { Ok(()) }
