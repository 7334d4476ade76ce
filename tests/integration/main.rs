//! Every integration test in one binary: one link instead of six, one GPU device for all.
//!
//! - [`reference`]: the f64 reference against the mathematics;
//! - [`cpu`], [`gpu`]: the fast paths against the reference (DESIGN section 18 bars), with the
//!   helpers they share in [`common`] (tracks, specs, generators) and [`fast`] (comparisons);
//! - [`shaders`]: the WGSL program without a GPU (naga) and the facts Rust shares with it;
//! - [`cli`], [`bake`]: the command line end to end, real files and hostile ones;
//! - [`play`]: the playback runtime against the bake and an independent blend;
//! - [`acl`]: the side-by-side with ACL's harness, built and run once;
//! - [`architecture`]: `ARCHITECTURE.md`'s crates, layers and orders, checked against the
//!   manifests and the imports.

#[allow(dead_code)]
mod common;
#[allow(dead_code)]
mod fast;

mod acl;
mod architecture;
mod cpu;
mod reference;

#[cfg(feature = "gpu")]
mod gpu;
#[cfg(feature = "gpu")]
mod shaders;

#[cfg(feature = "cli")]
mod bake;
#[cfg(feature = "cli")]
mod cli;
#[cfg(feature = "cli")]
mod play;

#[cfg(feature = "gpu")]
use quatcurve::gpu::GpuDevice;
#[cfg(feature = "gpu")]
use std::sync::OnceLock;

#[cfg(feature = "gpu")]
/// The one GPU evaluator of the test binary (tests that need other limits take
/// [`GpuDevice::share_device`]), or None (skip) when there is no adapter and none is required.
pub fn shared_gpu() -> Option<&'static GpuDevice> {
    static GPU: OnceLock<Option<GpuDevice>> = OnceLock::new();
    GPU.get_or_init(|| match GpuDevice::new() {
        Ok(g) => {
            eprintln!("GPU tests on: {}", g.adapter_name());
            Some(g)
        }
        Err(e) if std::env::var("QUATCURVE_REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("QUATCURVE_REQUIRE_GPU=1 but {e}")
        }
        Err(e) => {
            eprintln!("skipped: no GPU adapter ({e})");
            None
        }
    })
    .as_ref()
}
