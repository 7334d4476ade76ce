//! The compiled half of the Python package (DESIGN section 9). `quatcurve/__init__.py` checks
//! and shapes the user's arrays (one track or a batch, shared or per-track times) and calls
//! [`evaluate_batch`] with C-contiguous float64 arrays of fixed rank; this file builds the
//! library's batch from them, evaluates with the GIL released, and hands the samples back as
//! one numpy array `[tracks, samples, channels]` that owns the evaluator's buffer (no copy).
//! [`bake_files`] fills the library's [`BakeJob`] (the same job `quatcurve bake` runs) and
//! returns its per-input report as dictionaries.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use quatcurve::bake::{BakeJob, Shard};
use quatcurve::{Batch, CurveSpec, Device, DeviceChoice, EvalJob, Row, SampleTimes, Sampling, Track};
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::OnceLock;

fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

fn parse<T: FromStr<Err = String>>(what: &str, text: &str) -> PyResult<T> {
    text.parse().map_err(|e| value_error(format!("{what}: {e}")))
}

/// The device for `choice`, opened once per process: creating a GPU device takes a good
/// fraction of a second, and a caller evaluating track by track should not pay it each time.
fn device(choice: DeviceChoice) -> PyResult<&'static Device> {
    static DEVICES: [OnceLock<Device>; 4] = [OnceLock::new(), OnceLock::new(), OnceLock::new(), OnceLock::new()];
    let slot = &DEVICES[match choice {
        DeviceChoice::Auto => 0,
        DeviceChoice::Gpu => 1,
        DeviceChoice::Cpu => 2,
        DeviceChoice::Reference => 3,
    }];
    if let Some(device) = slot.get() {
        return Ok(device);
    }
    let opened = Device::open(choice).map_err(value_error)?;
    Ok(slot.get_or_init(|| opened))
}

/// Rows of a C-contiguous array.
fn rows<'a, const N: usize>(data: &'a [f64], per_track: usize, track: usize) -> impl Iterator<Item = [f64; N]> + 'a {
    data[track * per_track * N..(track + 1) * per_track * N].chunks_exact(N).map(|c| std::array::from_fn(|i| c[i]))
}

/// Evaluates `rotations` `[tracks, keys, 4]` (x, y, z, w) at `sample_times` `[tracks, m]`, or
/// on a uniform grid (`rate` Hz or `samples` per track) when it is `None`. Returns
/// `[tracks, m, 4]`, or `[tracks, m, 10]` with derivatives (rotation, body omega, alpha):
/// float64 from the reference, float32 from the fast paths. See `quatcurve.evaluate`.
#[pyfunction]
#[pyo3(signature = (
    rotations, times, sample_times, rate, samples, curve, order, knots, tangents, blend, looping,
    angular_velocities, derivatives, device
))]
#[allow(clippy::too_many_arguments)]
fn evaluate_batch<'py>(
    py: Python<'py>,
    rotations: PyReadonlyArray3<'py, f64>,
    times: Option<PyReadonlyArray2<'py, f64>>,
    sample_times: Option<PyReadonlyArray2<'py, f64>>,
    rate: Option<f64>,
    samples: Option<usize>,
    curve: &str,
    order: usize,
    knots: &str,
    tangents: &str,
    blend: &str,
    looping: bool,
    angular_velocities: Option<PyReadonlyArray3<'py, f64>>,
    derivatives: bool,
    device: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let spec = CurveSpec {
        curve: parse("curve", curve)?,
        order,
        knots: parse("knots", knots)?,
        tangents: parse("tangents", tangents)?,
        blend: parse("blend", blend)?,
        looping,
    };
    let choice: DeviceChoice = parse("device", device)?;
    let device = self::device(choice)?;
    let [count, keys, _] = [rotations.shape()[0], rotations.shape()[1], rotations.shape()[2]];
    let quats = rotations.as_slice().map_err(value_error)?;
    let key_times = times.as_ref().map(|t| t.as_slice()).transpose().map_err(value_error)?;
    let velocities = angular_velocities.as_ref().map(|v| v.as_slice()).transpose().map_err(value_error)?;
    let tracks: Vec<Track> = (0..count)
        .map(|i| Track {
            times: key_times.map(|t| t[i * keys..(i + 1) * keys].to_vec()),
            angular_velocities: velocities.map(|v| rows::<3>(v, keys, i).collect()),
            ..Track::from_rotations(rows::<4>(quats, keys, i).collect())
        })
        .collect();
    let sampled = match &sample_times {
        Some(s) => Some((s.shape()[1], s.as_slice().map_err(value_error)?)),
        None => None,
    };
    let sampling = match (rate, samples) {
        (_, Some(n)) => Sampling::Count(n),
        (Some(hz), None) => Sampling::Rate(hz),
        (None, None) => Sampling::Count(0),
    };
    let channels = Row { derivatives, matrix: false }.channels();
    let out = py
        .detach(|| -> Result<Samples, String> {
            let batch = Batch::from_tracks(&tracks, &spec).map_err(|e| e.to_string())?;
            let overrides: Vec<Option<&[f64]>> = match sampled {
                Some((m, s)) => (0..count).map(|i| Some(&s[i * m..(i + 1) * m])).collect(),
                None => Vec::new(),
            };
            let times = SampleTimes::new(&batch, &overrides, sampling).map_err(|e| e.to_string())?;
            times
                .equal_counts(&batch, "a numpy array of every track")
                .map_err(|e| format!("{e} (their domains differ): pass samples=N or sample_times for one count"))?;
            let job = EvalJob::new(&batch, &times).derivatives(derivatives);
            if choice == DeviceChoice::Reference {
                return Ok(Samples::F64(job.run().map_err(|e| e.to_string())?.to_rows()));
            }
            let (rows, _) = device.evaluate_f32(&job).map_err(|e| e.to_string())?;
            Ok(Samples::F32(rows.data))
        })
        .map_err(value_error)?;
    let per_track = |len: usize| len / channels / count.max(1);
    // The arrays take over the evaluator's buffers.
    match out {
        Samples::F64(data) => {
            let shape = [count, per_track(data.len()), channels];
            Ok(PyArray1::from_vec(py, data).reshape(shape)?.into_any())
        }
        Samples::F32(data) => {
            let shape = [count, per_track(data.len()), channels];
            Ok(PyArray1::from_vec(py, data).reshape(shape)?.into_any())
        }
    }
}

/// Samples in the precision the device computed them in.
enum Samples {
    F64(Vec<f64>),
    F32(Vec<f32>),
}

/// Bakes `inputs` (glTF/GLB/BVH files or directories; none: the built-in crowd) into `output`
/// as `quatcurve bake` does, with the GIL released. Returns one dictionary per input of this
/// shard: `source, clips, channels, keys, samples, seconds, max_key_error, status` (`ok`,
/// `resumed`, `failed`), `error`, `files` and `warnings`. See `quatcurve.bake`.
#[pyfunction]
#[pyo3(signature = (
    inputs, output, rate, exact_rate, curve, order, knots, tangents, blend, looping, texture, precision, atlas,
    preview, characters, shard, resume, jobs, allow_external_uris, device
))]
#[allow(clippy::too_many_arguments)]
fn bake_files<'py>(
    py: Python<'py>,
    inputs: Vec<PathBuf>,
    output: PathBuf,
    rate: f64,
    exact_rate: bool,
    curve: &str,
    order: usize,
    knots: &str,
    tangents: &str,
    blend: &str,
    looping: &str,
    texture: &str,
    precision: &str,
    atlas: bool,
    preview: bool,
    characters: usize,
    shard: Option<&str>,
    resume: bool,
    jobs: usize,
    allow_external_uris: bool,
    device: &str,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let choice: DeviceChoice = parse("device", device)?;
    let job = BakeJob {
        rate,
        exact_rate,
        spec: CurveSpec {
            curve: parse("curve", curve)?,
            order,
            knots: parse("knots", knots)?,
            tangents: parse("tangents", tangents)?,
            blend: parse("blend", blend)?,
            looping: false,
        },
        looping: parse("loop", looping)?,
        device: choice,
        allow_external_uris,
        texture: parse("texture", texture)?,
        precision: parse("precision", precision)?,
        atlas,
        preview,
        characters,
        shard: shard.map(Shard::parse).transpose().map_err(value_error)?,
        resume,
        jobs,
        ..BakeJob::new(inputs, output)
    };
    job.validate().map_err(value_error)?;
    let device = self::device(choice)?;
    let report = py.detach(|| job.run(device, &())).map_err(value_error)?;
    report
        .inputs
        .iter()
        .map(|input| {
            let row = PyDict::new(py);
            row.set_item("source", &input.source)?;
            row.set_item("clips", input.clips)?;
            row.set_item("channels", input.channels)?;
            row.set_item("keys", input.keys)?;
            row.set_item("samples", input.samples)?;
            row.set_item("seconds", input.seconds)?;
            row.set_item("max_key_error", input.max_key_error)?;
            let status = match &input.outcome {
                Ok(_) if input.resumed => "resumed",
                Ok(_) => "ok",
                Err(_) => "failed",
            };
            row.set_item("status", status)?;
            row.set_item("error", input.outcome.as_ref().err().map(ToString::to_string))?;
            row.set_item("files", input.outcome.as_ref().map_or_else(|_| Vec::new(), Clone::clone))?;
            row.set_item("warnings", &input.warnings)?;
            Ok(row)
        })
        .collect()
}

/// The compiled module, `quatcurve._quatcurve`.
#[pymodule]
fn _quatcurve(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(evaluate_batch, m)?)?;
    m.add_function(wrap_pyfunction!(bake_files, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // The front ends' defaults, from the library (the Python signatures use these).
    m.add("DEFAULT_CURVE", quatcurve::DEFAULT_CURVE.name())?;
    m.add("DEFAULT_RATE", quatcurve::DEFAULT_RATE)?;
    m.add("DEFAULT_CHARACTERS", quatcurve::bake::crowd::CHARACTERS)?;
    Ok(())
}
