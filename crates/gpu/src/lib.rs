//! The GPU path: WGSL compute shaders (in `shaders/`) evaluating the same packed batch as the
//! reference, in f32, through wgpu.
//!
//! - [`program`]: a compute program compiled on the device from naga's reflection of the WGSL
//!   (`quatcurve-shader`).
//! - [`layout`]: host twins of the kernel's structs; packing and chunking.
//! - [`context`]: [`GpuContext`], one device and the calls every pass makes.
//! - [`evaluator`]: [`GpuDevice`], the GPU device: the evaluation kernel here, forward
//!   kinematics, skinning and playback in their files; created once and reused.
//! - [`fk`]: [`ForwardKinematics`], bake's model matrices on the same device.
//! - [`skinning`]: [`MeshSkinning`], vertex textures' skinned meshes on the same device.
//! - [`playback`]: [`PosePalettes`], crowd playback's blend, forward kinematics and skin
//!   palettes in one submission; [`CurvePalettes`], the same from curves kept on the device.

pub mod context;
pub mod error;
pub mod evaluator;
pub mod fk;
pub mod layout;
pub mod playback;
pub mod program;
pub mod skinning;

pub use context::GpuContext;
pub use error::GpuError;
pub use evaluator::{GpuDevice, GpuOutput, PreparedBatch};
pub use fk::ForwardKinematics;
pub use playback::{CurvePalettes, PosePalettes};
pub use skinning::MeshSkinning;

/// Runs `f` (which creates a wgpu instance, adapter or device) without the display-server
/// noise it would print on a server. wgpu's Vulkan instance enables the Wayland surface
/// extension, and Mesa's drivers then ask libwayland for a display, which prints "error:
/// XDG_RUNTIME_DIR is invalid or not set in the environment." (twice) where the variable is
/// missing or not absolute. For the duration of `f` such a variable is the system's temporary
/// directory (absolute: libwayland then finds no display there, silently), and it is put back
/// after. The CLI and the Python package open their devices through this too.
pub(crate) fn quietly<T>(f: impl FnOnce() -> T) -> T {
    const NAME: &str = "XDG_RUNTIME_DIR";
    let given = std::env::var_os(NAME);
    let usable = given.as_ref().is_some_and(|d| std::path::Path::new(d).is_absolute());
    if !cfg!(target_os = "linux") || usable {
        return f();
    }
    std::env::set_var(NAME, std::env::temp_dir());
    let result = f();
    match given {
        Some(value) => std::env::set_var(NAME, value),
        None => std::env::remove_var(NAME),
    }
    result
}
