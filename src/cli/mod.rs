//! The subcommands. Each parses its arguments, builds library jobs and reports; the maths and
//! file formats live in the library.

pub mod analyze;
pub mod bake;
pub mod bench;
pub mod bench_fitted;
pub mod bench_playback;
pub mod eval;
pub mod fit;
mod measure;
pub mod play;
pub mod shaders;
pub mod view;
pub mod vocabulary;

use quatcurve::{Device, DeviceChoice, DeviceError};
use std::io::Write;
use std::path::Path;

/// A failure with the exit code it maps to.
pub enum Failure {
    /// Bad usage or bad input: exit 2.
    Input(String),
    /// Device or internal failure: exit 1.
    Internal(String),
}

impl From<DeviceError> for Failure {
    fn from(e: DeviceError) -> Self {
        if e.is_device_failure() {
            Failure::Internal(e.to_string())
        } else {
            Failure::Input(e.to_string())
        }
    }
}

impl Failure {
    /// Prefixes the message with where it happened (a file name).
    pub fn context(self, what: &str) -> Self {
        match self {
            Failure::Input(msg) => Failure::Input(format!("{what}: {msg}")),
            Failure::Internal(msg) => Failure::Internal(format!("{what}: {msg}")),
        }
    }
}

/// The flag of an option the library names (`max_texture_size` is `--max-texture-size`; the
/// jobs' `inputs` is `--input`, given once per file).
pub fn flag(option: &str) -> String {
    match option {
        "inputs" => "--input".into(),
        _ => format!("--{}", option.replace('_', "-")),
    }
}

/// Opens the device `choice`; the library's message (`gpu: no adapter ...`) gets the flag
/// that chose it in front (`--device gpu: no adapter ...`).
pub fn open_device(choice: DeviceChoice, flag: &str) -> Result<Device, Failure> {
    Device::open(choice).map_err(|e| match e.is_device_failure() {
        true => Failure::Internal(format!("{flag} {e}")),
        false => Failure::Input(format!("{flag} {e}")),
    })
}

pub use quatcurve::options::{names, CurveOptions};

/// Writes a finished text document to standard output; a reader that stops early (`| head`)
/// is not a failure of ours.
pub fn print_stdout(write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<(), Failure> {
    let mut stdout = std::io::stdout().lock();
    match write(&mut stdout).and_then(|()| stdout.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(Failure::Internal(format!("standard output: {e}"))),
        Ok(()) => Ok(()),
    }
}

/// Says on stderr that `path` was written, so that stdout keeps to the report (`--json`).
pub fn wrote(path: &Path) {
    eprintln!("wrote {}", path.display());
}

/// Every clip's rotation channels of the fitted container at `path`, as tracks
/// ([`quatcurve::qcf::Container::rotation_tracks`]).
pub fn read_container_tracks(path: &Path) -> Result<(String, Vec<quatcurve::Track>), Failure> {
    let source = path.display().to_string();
    let container = quatcurve::qcf::Container::read(path).map_err(|e| Failure::Input(format!("{source}: {e}")))?;
    Ok((source, container.rotation_tracks()))
}

/// Whether `input` is a fitted container, by its extension.
pub fn is_container(input: Option<&Path>) -> bool {
    let extension = input.and_then(|p| p.extension()).and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    extension.as_deref() == Some(quatcurve::qcf::EXTENSION)
}

/// The tracks of `--input` (JSON, or `.npz`/`.npy` arrays keyed at `key_rate`), or the built-in
/// demo without one; with the name messages give the source.
pub fn read_tracks(input: Option<&Path>, key_rate: Option<f64>) -> Result<(String, Vec<quatcurve::Track>), Failure> {
    let Some(path) = input else {
        return Ok(("built-in demo".to_string(), quatcurve::io::demo_tracks()));
    };
    if is_container(Some(path)) {
        return Err(Failure::Input(format!(
            "{}: a fitted container holds curves, not keys: eval and bake read it",
            path.display()
        )));
    }
    let arrays = matches!(
        path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref(),
        Some("npz" | "npy")
    );
    let tracks = if arrays {
        quatcurve::arrays::read_tracks(path, key_rate).map_err(|e| Failure::Input(e.to_string()))?
    } else {
        if key_rate.is_some() {
            return Err(Failure::Input(
                "--key-rate applies to .npz and .npy input; JSON tracks carry their own times".into(),
            ));
        }
        quatcurve::io::read_track_file(path).map_err(|e| Failure::Input(e.to_string()))?.tracks
    };
    Ok((path.display().to_string(), tracks))
}
