//! The compiled half of the Python package (DESIGN section 15). `quatcurve/__init__.py` checks
//! and shapes the user's arrays (one track, a rectangular batch or a list of tracks of their
//! own lengths; quaternions, rotation vectors or matrices) and calls [`evaluate_tracks`] with
//! them flat: C-contiguous float64 rows and each track's offsets. This file builds the
//! library's batch from them, evaluates with the GIL released, and hands the samples back as
//! one numpy array `[samples, channels]` (owning the evaluator's buffer when the output is
//! quaternions) with each track's offsets.
//! [`bake_files`] fills the library's [`BakeJob`] (the same job `quatcurve bake` runs) and
//! returns its per-input report as dictionaries; [`decode_container`] runs the runtime decoder
//! of fitted containers.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use quatcurve::bake::budget::{ChosenRate, Worst};
use quatcurve::bake::{fitted_frame_grid, grid_times, poses, BakeJob, BakeOptions, Shard};
use quatcurve::fit::job::{FitJob, FitOptions};
use quatcurve::formats::smpl::SmplFile;
use quatcurve::options::EvalOptions;
use quatcurve::qcf::decoder::Decoder;
use quatcurve::{Device, DeviceChoice, EvalJob, FloatOutput, QuatF64, Row, SampleTimes, Track, Vec3F64};
use std::path::PathBuf;
use std::sync::OnceLock;

fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A job's options from the JSON object of those Python was given by name
/// ([`quatcurve::options::from_named`]: the rest at their defaults).
fn named<T>(options: &str) -> PyResult<T>
where
    T: Default + serde::Serialize + for<'de> serde::Deserialize<'de>,
{
    let given: serde_json::Map<String, serde_json::Value> = serde_json::from_str(options).map_err(value_error)?;
    quatcurve::options::from_named(&given).map_err(value_error)
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

/// `offsets` as ranges `offsets[i]..offsets[i + 1]` of an array of `len` rows: from 0 to
/// `len`, never decreasing (the Python side builds them; a caller of the compiled module
/// directly gets an error, not a panic).
fn ranges(what: &str, offsets: &[i64], len: usize) -> PyResult<Vec<std::ops::Range<usize>>> {
    let ok = offsets.first() == Some(&0)
        && offsets.last().is_some_and(|&l| usize::try_from(l).ok() == Some(len))
        && offsets.windows(2).all(|w| w[0] <= w[1]);
    if !ok {
        return Err(value_error(format!("{what} offsets must rise from 0 to {len}")));
    }
    Ok(offsets.windows(2).map(|w| w[0] as usize..w[1] as usize).collect())
}

/// How far a matrix given as a rotation may be from orthonormal with determinant 1 (float32
/// matrices written by other tools are a few 1e-7 off).
const MATRIX_TOLERANCE: f64 = 1e-4;

/// How rotations are written: quaternions `x, y, z, w`, rotation vectors (axis times angle,
/// radians), or row-major 3x3 matrices (scipy's `as_quat`, `as_rotvec`, `as_matrix`).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Form {
    Quat,
    Rotvec,
    Matrix,
}

impl Form {
    fn parse(what: &str, name: &str) -> PyResult<Self> {
        match name {
            "quat" => Ok(Form::Quat),
            "rotvec" => Ok(Form::Rotvec),
            "matrix" => Ok(Form::Matrix),
            _ => Err(value_error(format!("{what} must be quat, rotvec or matrix, not {name}"))),
        }
    }

    /// Floats per rotation.
    fn width(self) -> usize {
        match self {
            Form::Quat => 4,
            Form::Rotvec => 3,
            Form::Matrix => 9,
        }
    }

    /// A rotation written this way as a quaternion `x, y, z, w` (quaternions as given: the
    /// library checks and normalizes keys); a matrix must be a rotation, orthonormal with
    /// determinant 1 within [`MATRIX_TOLERANCE`].
    fn to_quat(self, v: &[f64]) -> Result<[f64; 4], String> {
        Ok(match self {
            Form::Quat => [v[0], v[1], v[2], v[3]],
            Form::Rotvec => QuatF64::from_rotation_vector(Vec3F64::new(v[0], v[1], v[2])).to_array(),
            Form::Matrix => {
                let m = [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]];
                // |M^T M - I| (largest entry) and the determinant.
                let off = (0..9)
                    .map(|k| {
                        let (i, j) = (k / 3, k % 3);
                        let dot: f64 = (0..3).map(|r| m[r][i] * m[r][j]).sum();
                        (dot - if i == j { 1.0 } else { 0.0 }).abs()
                    })
                    .fold(0.0, f64::max);
                let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                    - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                    + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
                if !(off <= MATRIX_TOLERANCE && (det - 1.0).abs() <= MATRIX_TOLERANCE) {
                    return Err(format!(
                        "is not a rotation matrix: |M^T M - I| = {off:.3e} and det = {det:.6}, where a rotation has 0 and 1 \
                         (within {MATRIX_TOLERANCE})"
                    ));
                }
                QuatF64::from_mat3(m).to_array()
            }
        })
    }

    /// A unit quaternion written this way into `out` (`width` floats).
    fn write(self, q: QuatF64, out: &mut [f64]) {
        match self {
            Form::Quat => out.copy_from_slice(&q.to_array()),
            Form::Rotvec => out.copy_from_slice(&q.to_rotation_vector().to_array()),
            Form::Matrix => out.copy_from_slice(&q.to_mat3().concat()),
        }
    }
}

/// Output rows `[x, y, z, w, (omega, alpha)]` rewritten with the rotation in `form`.
fn rewrite<T: Copy + Into<f64>>(rows: &[T], channels: usize, form: Form, from: impl Fn(f64) -> T) -> Vec<T> {
    let width = form.width() + channels - 4;
    let mut out = Vec::with_capacity(rows.len() / channels * width);
    let mut rotation = [0.0; 9];
    for row in rows.chunks_exact(channels) {
        let q = QuatF64::from_array(std::array::from_fn(|i| row[i].into())).normalize();
        form.write(q, &mut rotation[..form.width()]);
        out.extend(rotation[..form.width()].iter().map(|&v| from(v)));
        out.extend_from_slice(&row[4..]);
    }
    out
}

/// Evaluates tracks given flat: track `i`'s keys are rows `key_offsets[i]..key_offsets[i + 1]`
/// of `rotations` (written as `rotation_type`), its key times the same entries of `times`
/// (default `0, 1, ...`), its samples the entries `sample_offsets[i]..` of `sample_times`, or
/// the uniform grid the options give (`rate` Hz or `samples` per track). `options` is a JSON
/// object of the library's eval options by name (`quatcurve::options::EvalOptions`: the
/// keywords of `quatcurve.evaluate`), each one not given at its default. Returns the samples
/// `[total, C]`, rows of the rotation in `output` form (4, 3 or 9 floats) then with derivatives
/// body omega and alpha (float64 from the reference, float32 from the fast paths), and each
/// track's rows as offsets. With `equal_counts`, tracks whose sample counts differ are an error
/// (a rectangular array). See `quatcurve.evaluate`.
#[pyfunction]
#[pyo3(signature = (
    rotations, rotation_type, key_offsets, times, sample_times, sample_offsets, angular_velocities, output,
    equal_counts, options
))]
#[allow(clippy::too_many_arguments)]
fn evaluate_tracks<'py>(
    py: Python<'py>,
    rotations: PyReadonlyArray2<'py, f64>,
    rotation_type: &str,
    key_offsets: PyReadonlyArray1<'py, i64>,
    times: Option<PyReadonlyArray1<'py, f64>>,
    sample_times: Option<PyReadonlyArray1<'py, f64>>,
    sample_offsets: Option<PyReadonlyArray1<'py, i64>>,
    angular_velocities: Option<PyReadonlyArray2<'py, f64>>,
    output: &str,
    equal_counts: bool,
    options: &str,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let options: EvalOptions = named(options)?;
    let (derivatives, choice) = (options.derivatives, options.device);
    let (form, out_form) = (Form::parse("rotation_type", rotation_type)?, Form::parse("output", output)?);
    let device = self::device(choice)?;
    let width = rotations.shape()[1];
    if width != form.width() {
        return Err(value_error(format!("{rotation_type} rotations have {} floats each, not {width}", form.width())));
    }
    let values = rotations.as_slice().map_err(value_error)?;
    let key_ranges = ranges("key", key_offsets.as_slice().map_err(value_error)?, rotations.shape()[0])?;
    let key_times = times.as_ref().map(|t| t.as_slice()).transpose().map_err(value_error)?;
    let velocities = angular_velocities.as_ref().map(|v| v.as_slice()).transpose().map_err(value_error)?;
    if key_times.is_some_and(|t| t.len() != rotations.shape()[0])
        || velocities.is_some_and(|v| v.len() != 3 * rotations.shape()[0])
    {
        return Err(value_error("times and angular_velocities need one entry per key"));
    }
    let mut tracks = Vec::with_capacity(key_ranges.len());
    for (index, keys) in key_ranges.iter().enumerate() {
        let rows = values[width * keys.start..width * keys.end].chunks_exact(width);
        let rotations = rows
            .enumerate()
            .map(|(key, r)| form.to_quat(r).map_err(|e| value_error(format!("track {index}: key {key} {e}"))))
            .collect::<PyResult<Vec<_>>>()?;
        tracks.push(Track {
            times: key_times.map(|t| t[keys.clone()].to_vec()),
            angular_velocities: velocities
                .map(|v| v[3 * keys.start..3 * keys.end].chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()),
            ..Track::from_rotations(rotations)
        });
    }
    let sampled = match (&sample_times, &sample_offsets) {
        (Some(s), Some(o)) => {
            let s = s.as_slice().map_err(value_error)?;
            Some((s, ranges("sample", o.as_slice().map_err(value_error)?, s.len())?))
        }
        _ => None,
    };
    if sampled.as_ref().is_some_and(|(_, r)| r.len() != tracks.len()) {
        return Err(value_error("sample_times need one list per track"));
    }
    // Sample times given for every track replace the grid.
    let sampling = options.sampling().map_err(value_error)?;
    let channels = Row { derivatives, matrix: false }.channels();
    let (out, offsets) = py
        .detach(|| -> Result<(Samples, Vec<i64>), String> {
            let batch = options.batch(&tracks).map_err(|e| e.to_string())?;
            let overrides: Vec<Option<&[f64]>> = match &sampled {
                Some((s, r)) => r.iter().map(|r| Some(&s[r.clone()])).collect(),
                None => Vec::new(),
            };
            let times = SampleTimes::new(&batch, &overrides, sampling).map_err(|e| e.to_string())?;
            if equal_counts {
                times.equal_counts(&batch, "a numpy array of every track").map_err(|e| {
                    format!(
                        "{e} (their domains differ): pass samples=N or sample_times for one count, or a list of tracks"
                    )
                })?;
            }
            let offsets = times.offsets().iter().map(|&o| o as i64).collect();
            let job = EvalJob::new(&batch, &times).derivatives(derivatives);
            let samples = if choice == DeviceChoice::Reference {
                Samples::F64(job.run().map_err(|e| e.to_string())?.to_rows())
            } else {
                let mut rows = FloatOutput::default();
                device.evaluate_into(&job, &mut rows).map_err(|e| e.to_string())?;
                Samples::F32(rows.data)
            };
            // Quaternions stay in the evaluator's buffer; other forms are written anew.
            Ok((
                match (samples, out_form) {
                    (samples, Form::Quat) => samples,
                    (Samples::F64(rows), _) => Samples::F64(rewrite(&rows, channels, out_form, |v| v)),
                    (Samples::F32(rows), _) => Samples::F32(rewrite(&rows, channels, out_form, |v| v as f32)),
                },
                offsets,
            ))
        })
        .map_err(value_error)?;
    let width = out_form.width() + channels - 4;
    let offsets = PyArray1::from_vec(py, offsets).into_any();
    // The arrays take over the buffers.
    let data = match out {
        Samples::F64(data) => {
            let rows = data.len() / width;
            PyArray1::from_vec(py, data).reshape([rows, width])?.into_any()
        }
        Samples::F32(data) => {
            let rows = data.len() / width;
            PyArray1::from_vec(py, data).reshape([rows, width])?.into_any()
        }
    };
    Ok((data, offsets))
}

/// Samples in the precision the device computed them in.
enum Samples {
    F64(Vec<f64>),
    F32(Vec<f32>),
}

/// Bakes `inputs` (glTF/GLB/BVH files or directories; none: the built-in crowd) into `output`
/// as `quatcurve bake` does, with the GIL released. `options` is a JSON object of the
/// library's bake options by name (`quatcurve::bake::BakeOptions`: the keywords of
/// `quatcurve.bake`), each one not given at its default. Returns one dictionary per input of
/// this shard: `source, clips, channels, keys, samples, seconds, max_key_error, status`
/// (`ok`, `resumed`, `failed`), `error`, `files`, `warnings`, `rates` (with an error budget:
/// per clip, [`chosen_rate`]) and `skinning` (vertex textures: `{vertex_frames, seconds}`,
/// else `None`). See `quatcurve.bake`.
#[pyfunction]
#[pyo3(signature = (inputs, output, options, shard, resume, jobs))]
fn bake_files<'py>(
    py: Python<'py>,
    inputs: Vec<PathBuf>,
    output: PathBuf,
    options: &str,
    shard: Option<&str>,
    resume: bool,
    jobs: usize,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let options: BakeOptions = named(options)?;
    let choice = options.device;
    let job = BakeJob {
        options,
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
            let rates = input.rates.iter().map(|c| chosen_rate(py, c)).collect::<PyResult<Vec<_>>>()?;
            row.set_item("rates", rates)?;
            let skinning = match input.skinning {
                Some((vertex_frames, seconds)) => {
                    let work = PyDict::new(py);
                    work.set_item("vertex_frames", vertex_frames)?;
                    work.set_item("seconds", seconds)?;
                    Some(work)
                }
                None => None,
            };
            row.set_item("skinning", skinning)?;
            Ok(row)
        })
        .collect()
}

/// SMPL-family poses `[frames, joints * 3]` (axis-angle), optionally the root's `trans`
/// `[frames, 3]` and other per-frame arrays (`per_frame`: name, shape, values flattened) at
/// `rate` frames per second, resampled by the library's bake options by name (`options`:
/// `rate` the new rate, `exact_rate`, the curve's, `loop`, `device`), with the GIL released.
/// Returns the poses, the translation (or `None`), the per-frame arrays (name, values
/// flattened, shape), the rate of the frames and the warnings a bake would give. See
/// `quatcurve.resample_poses`.
#[pyfunction]
#[pyo3(signature = (poses, trans, per_frame, rate, options))]
#[allow(clippy::type_complexity)]
fn resample_pose_arrays<'py>(
    py: Python<'py>,
    poses: PyReadonlyArray2<'py, f64>,
    trans: Option<PyReadonlyArray2<'py, f64>>,
    per_frame: Vec<(String, Vec<u64>, PyReadonlyArray1<'py, f64>)>,
    rate: f64,
    options: &str,
) -> PyResult<(
    Bound<'py, PyAny>,
    Option<Bound<'py, PyAny>>,
    Vec<(String, Bound<'py, PyAny>, Vec<u64>)>,
    f64,
    Vec<String>,
)> {
    let options: BakeOptions = named(options)?;
    let device = self::device(options.device)?;
    let width = poses.shape()[1];
    let per_frame = per_frame
        .into_iter()
        .map(|(name, shape, values)| Ok((name, shape, values.as_slice().map_err(value_error)?.to_vec())))
        .collect::<PyResult<Vec<_>>>()?;
    let file = SmplFile::from_arrays(
        poses.as_slice().map_err(value_error)?,
        width,
        trans.as_ref().map(|t| t.as_slice()).transpose().map_err(value_error)?,
        rate,
        &per_frame,
    )
    .map_err(value_error)?;
    let (resampled, warnings) = py.detach(|| poses::resample(file, &options, device)).map_err(value_error)?;
    let frames = resampled.frames;
    let poses = PyArray1::from_vec(py, resampled.poses).reshape([frames, width])?.into_any();
    let trans =
        resampled.trans.map(|t| PyArray1::from_vec(py, t).reshape([frames, 3]).map(Bound::into_any)).transpose()?;
    let per_frame = resampled
        .per_frame
        .into_iter()
        .map(|(name, shape, values)| (name, PyArray1::from_vec(py, values).into_any(), shape))
        .collect();
    Ok((poses, trans, per_frame, resampled.rate, warnings))
}

/// One clip's rate chosen by an error budget, as a dictionary: `clip, rate, frames, rotation`
/// and `position` (each `{value, joint, time}`: degrees or cm), `bytes, fixed_rate_bytes`.
fn chosen_rate<'py>(py: Python<'py>, c: &ChosenRate) -> PyResult<Bound<'py, PyDict>> {
    let worst = |w: &Worst| -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("value", w.value)?;
        d.set_item("joint", &w.joint)?;
        d.set_item("time", w.time)?;
        Ok(d)
    };
    let d = PyDict::new(py);
    d.set_item("clip", &c.clip)?;
    d.set_item("rate", c.measured.rate)?;
    d.set_item("frames", c.measured.frames)?;
    d.set_item("rotation", worst(&c.measured.rotation)?)?;
    d.set_item("position", worst(&c.measured.position)?)?;
    d.set_item("bytes", c.bytes)?;
    d.set_item("fixed_rate_bytes", c.fixed_rate_bytes)?;
    Ok(d)
}

/// `quatcurve fit` in-process (DESIGN section 16): `options` a JSON object of the library's
/// fit options by name (`quatcurve::fit::job::FitOptions`: the keywords of `quatcurve.fit`);
/// the report as JSON text (the Python side parses it), or `ValueError` for a job refused
/// before the work.
#[pyfunction]
#[pyo3(signature = (inputs, output, options))]
fn fit_files(py: Python<'_>, inputs: Vec<PathBuf>, output: PathBuf, options: &str) -> PyResult<String> {
    let options: FitOptions = named(options)?;
    let job = FitJob { inputs, output, options };
    let report = py.detach(|| job.run(&|_, _| {})).map_err(value_error)?;
    serde_json::to_string(&report).map_err(value_error)
}

/// A fitted container's clips through the runtime decoder (DESIGN section 16): the joints'
/// names and parents (-1 for a root), then per clip its name, its frame times at `rate` (the
/// source's when `None`, fitted to the clip's span as a bake's) and the local poses there,
/// `[frames, joints * 10]` f32 (rotation `x, y, z, w`, translation, scale). See
/// `quatcurve.decode`.
#[pyfunction]
#[pyo3(signature = (path, rate))]
#[allow(clippy::type_complexity)]
fn decode_container<'py>(
    py: Python<'py>,
    path: PathBuf,
    rate: Option<f64>,
) -> PyResult<(Vec<String>, Vec<i64>, Vec<(String, Bound<'py, PyAny>, Bound<'py, PyAny>)>)> {
    let failed = |e: &dyn std::fmt::Display| value_error(format!("{}: {e}", path.display()));
    let bytes = std::fs::read(&path).map_err(|e| failed(&e))?;
    let decoder = Decoder::from_bytes(&bytes).map_err(|e| failed(&format!("fitted container {e}")))?;
    let names = decoder.joints.iter().map(|j| j.name.clone()).collect();
    let parents = decoder.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect();
    let mut clips = Vec::with_capacity(decoder.clips().len());
    for index in 0..decoder.clips().len() {
        let mut clip = decoder.open(index).map_err(|e| failed(&format!("fitted container {e}")))?;
        let [start, end] = clip.span();
        let (grid, _) = fitted_frame_grid(start, end, rate.unwrap_or(clip.rate)).map_err(|e| failed(&e))?;
        let times = grid_times(grid);
        let width = clip.pose_floats();
        let mut poses = vec![0.0f32; times.len() * width];
        py.detach(|| clip.poses(&times, &mut poses)).map_err(|e| failed(&e))?;
        let frames = times.len();
        let poses = PyArray1::from_vec(py, poses).reshape([frames, width])?.into_any();
        clips.push((clip.name.to_string(), PyArray1::from_vec(py, times).into_any(), poses));
    }
    Ok((names, parents, clips))
}

/// The compiled module, `quatcurve._quatcurve`.
#[pymodule]
fn _quatcurve(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(evaluate_tracks, m)?)?;
    m.add_function(wrap_pyfunction!(bake_files, m)?)?;
    m.add_function(wrap_pyfunction!(fit_files, m)?)?;
    m.add_function(wrap_pyfunction!(resample_pose_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(decode_container, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // The front ends' defaults, from the library (the Python signatures use these).
    m.add("DEFAULT_CURVE", quatcurve::DEFAULT_CURVE.name())?;
    m.add("DEFAULT_RATE", quatcurve::DEFAULT_RATE)?;
    // Each job's options by name with their defaults, as JSON (`quatcurve.EVAL_OPTIONS`, ...).
    m.add("EVAL_OPTIONS", serde_json::to_string(&EvalOptions::DEFAULT).map_err(value_error)?)?;
    m.add("BAKE_OPTIONS", serde_json::to_string(&BakeOptions::DEFAULT).map_err(value_error)?)?;
    m.add("FIT_OPTIONS", serde_json::to_string(&FitOptions::DEFAULT).map_err(value_error)?)?;
    Ok(())
}
