//! `quatcurve eval` end to end: files in, files out, values checked; exit codes and messages.

use crate::common::{f64_bytes, npy_bytes, write_npz};
use assert_cmd::Command;
use quatcurve::{Batch, Curve, CurveSpec, QuatF64, Tangents, Track, TrackFile, Vec3F64};
use std::path::Path;
use std::process::Output;

fn quatcurve(args: &[&str]) -> Output {
    Command::cargo_bin("quatcurve").expect("binary built").args(args).output().expect("binary runs")
}

fn write_tracks(dir: &Path, tracks: &[Track]) -> String {
    let path = dir.join("tracks.json");
    std::fs::write(&path, serde_json::to_string(&TrackFile { tracks: tracks.to_vec() }).unwrap()).unwrap();
    path.display().to_string()
}

fn sample_tracks() -> Vec<Track> {
    let keys = |phase: f64| -> Vec<[f64; 4]> {
        (0..5)
            .map(|i| QuatF64::exp(Vec3F64::new(0.3 * (i as f64 + phase).sin(), 0.2 * i as f64, 0.1)).to_array())
            .collect()
    };
    vec![
        Track {
            name: Some("hips".into()),
            times: Some(vec![0.0, 0.5, 1.0, 1.5, 2.0]),
            angular_velocities: Some(vec![[0.5, 0.0, -2.0]; 5]),
            ..Track::from_rotations(keys(0.0))
        },
        Track {
            name: Some("spine".into()),
            angular_velocities: Some(vec![[0.0, 1.0, 0.0]; 5]),
            sample_times: Some(vec![3.0, -1.0, 0.25]),
            ..Track::from_rotations(keys(1.0))
        },
    ]
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn eval_writes_json_that_matches_the_library() {
    let dir = tempfile::tempdir().unwrap();
    let tracks = sample_tracks();
    let input = write_tracks(dir.path(), &tracks);
    let output = dir.path().join("out.json");
    let out = quatcurve(&[
        "eval",
        "--input",
        &input,
        "--output",
        output.to_str().unwrap(),
        "--curve",
        "hermite",
        "--tangents",
        "given",
        "--samples",
        "7",
        "--derivatives",
        "--device",
        "reference",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&output).unwrap()).unwrap();
    assert_eq!(doc["curve"], "hermite");
    assert_eq!(doc["device"], "reference");
    let spec = CurveSpec { tangents: Tangents::Given, ..CurveSpec::new(Curve::Hermite) };
    let batch = Batch::from_tracks(&tracks, &spec).unwrap();
    // Track 0: 7 samples over [0, 2]; track 1: its own sample_times, echoed unclamped.
    let expected_times = [vec![0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0, 4.0 / 3.0, 5.0 / 3.0, 2.0], vec![3.0, -1.0, 0.25]];
    for (i, times) in expected_times.iter().enumerate() {
        let t = &doc["tracks"][i];
        assert_eq!(t["name"], ["hips", "spine"][i]);
        let got_times: Vec<f64> = serde_json::from_value(t["times"].clone()).unwrap();
        assert_eq!(got_times.len(), times.len());
        for (j, &time) in times.iter().enumerate() {
            assert!((got_times[j] - time).abs() < 1e-15);
            let s = quatcurve::evaluate(batch.view(i), got_times[j]);
            let q: [f64; 4] = serde_json::from_value(t["rotations"][j].clone()).unwrap();
            assert_eq!(q, s.rotation.to_array(), "JSON must round-trip f64 exactly");
            let w: [f64; 3] = serde_json::from_value(t["angular_velocity"][j].clone()).unwrap();
            assert_eq!(w, s.angular_velocity.to_array());
            let a: [f64; 3] = serde_json::from_value(t["angular_acceleration"][j].clone()).unwrap();
            assert_eq!(a, s.angular_acceleration.to_array());
        }
    }
}

#[test]
fn eval_rate_sampling_and_no_derivative_fields_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_tracks(dir.path(), &sample_tracks()[..1]);
    let out = quatcurve(&["eval", "--input", &input, "--curve", "slerp", "--rate", "4"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let times: Vec<f64> = serde_json::from_value(doc["tracks"][0]["times"].clone()).unwrap();
    assert_eq!(times, vec![0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0]);
    assert!(doc["tracks"][0].get("angular_velocity").is_none());
}

#[test]
fn eval_defaults_run_on_the_built_in_demo() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("demo.json");
    let out = quatcurve(&["eval", "--output", output.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("built-in demo"));
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&output).unwrap()).unwrap();
    assert_eq!(doc["curve"], "bspline-interp");
    assert_eq!(doc["tracks"].as_array().unwrap().len(), 3);
}

/// `--loop auto`, the default: a track that closes loops, and times outside the period wrap
/// (echoed as given); `--loop off` clamps them; `--loop on` with a track that does not
/// close, or a curve that cannot loop, is exit 2 naming the track.
#[test]
fn eval_loop_wraps_and_rejects_open_tracks_and_non_looping_curves() {
    let dir = tempfile::tempdir().unwrap();
    let closed: Vec<[f64; 4]> = (0..5)
        .map(|i| QuatF64::exp(Vec3F64::new(0.4 * (i as f64 * std::f64::consts::FRAC_PI_2).sin(), 0.1, 0.0)).to_array())
        .collect();
    let track =
        Track { name: Some("tail".into()), sample_times: Some(vec![0.5, 4.5, -3.5]), ..Track::from_rotations(closed) };
    let input = write_tracks(dir.path(), &[track]);
    let output = dir.path().join("out.json");
    let eval = |more: &[&str]| {
        let out = quatcurve(&[&["eval", "--input", &input, "--output", output.to_str().unwrap()][..], more].concat());
        assert!(out.status.success(), "{}", stderr(&out));
        let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&output).unwrap()).unwrap();
        let t = doc["tracks"][0].clone();
        assert_eq!(t["times"], serde_json::json!([0.5, 4.5, -3.5]));
        let q = |i: usize| QuatF64::from_array(serde_json::from_value(t["rotations"][i].clone()).unwrap());
        (q(0).angle_to(q(1)), q(0).angle_to(q(2)))
    };
    let (later, earlier) = eval(&["--device", "reference"]);
    assert!(later < 1e-12 && earlier < 1e-12, "4.5 and -3.5 wrap to 0.5 over a period of 4");
    let (later, earlier) = eval(&["--device", "reference", "--loop", "off"]);
    assert!(later > 1e-3 && earlier > 1e-3, "open, 4.5 and -3.5 are held at the ends");

    let open = write_tracks(dir.path(), &sample_tracks());
    let out = quatcurve(&["eval", "--input", &open, "--loop", "on"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("track 0 \"hips\"") && stderr(&out).contains("first rotation"), "{}", stderr(&out));
    let out = quatcurve(&["eval", "--input", &input, "--loop", "on", "--curve", "bezier"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("bezier cannot loop"), "{}", stderr(&out));
}

#[test]
fn bad_input_exits_2_naming_file_track_and_key_and_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let mut tracks = sample_tracks();
    tracks[1].rotations[3] = [0.0, 0.0, 0.0, 0.0];
    let input = write_tracks(dir.path(), &tracks);
    let output = dir.path().join("out.json");
    std::fs::write(&output, "previous result").unwrap();
    let out = quatcurve(&["eval", "--input", &input, "--output", output.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let msg = stderr(&out);
    assert!(msg.contains("tracks.json") && msg.contains("track 1 \"spine\"") && msg.contains("key 3"), "{msg}");
    assert_eq!(msg.lines().count(), 1, "one line: {msg}");
    assert_eq!(std::fs::read_to_string(&output).unwrap(), "previous result", "old output must survive");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(leftovers.len(), 2, "no temporary file left: {leftovers:?}");
}

#[test]
fn malformed_json_and_missing_file_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.json");
    std::fs::write(&path, "{\"tracks\": [{\"rotations\": [[0, 0, 0, 1], [0, 0]]}]}").unwrap();
    let out = quatcurve(&["eval", "--input", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("broken.json") && stderr(&out).contains("line 1"), "{}", stderr(&out));
    let out = quatcurve(&["eval", "--input", dir.path().join("absent.json").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("absent.json"), "{}", stderr(&out));
}

#[test]
fn usage_errors_exit_2() {
    for args in [
        &["eval", "--curve", "spiral"][..],
        &["eval", "--samples", "3", "--rate", "4"],
        &["eval", "--samples", "0"],
        &["eval", "--rate", "-2"],
        &["eval", "--curve", "bspline", "--order", "5"],
    ] {
        let out = quatcurve(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
    }
}

#[test]
fn unavailable_device_exits_1_without_fallback() {
    // A backend that does not exist on Linux: no adapter, so --device gpu must fail.
    let no_gpu = |device: &str| {
        Command::cargo_bin("quatcurve")
            .unwrap()
            .args(["eval", "--device", device, "--samples", "2"])
            .env("WGPU_BACKEND", "metal")
            .output()
            .unwrap()
    };
    let out = no_gpu("gpu");
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("--device gpu"), "{}", stderr(&out));
    assert!(out.stdout.is_empty(), "no silent fallback output");
    // auto falls back to the fast CPU path and says so in the output.
    let out = no_gpu("auto");
    assert!(out.status.success(), "{}", stderr(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(doc["device"].as_str().unwrap().starts_with("cpu: f32x8"), "{}", doc["device"]);
}

#[test]
fn eval_on_the_gpu_names_the_adapter_and_agrees_with_the_reference() {
    if crate::shared_gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = write_tracks(dir.path(), &sample_tracks());
    let run = |device: &str| {
        let out = quatcurve(&[
            "eval",
            "--input",
            &input,
            "--curve",
            "squad",
            "--samples",
            "9",
            "--derivatives",
            "--device",
            device,
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let (gpu, reference) = (run("gpu"), run("reference"));
    assert!(gpu["device"].as_str().unwrap().starts_with("gpu: "), "{}", gpu["device"]);
    for t in 0..2 {
        for j in 0..gpu["tracks"][t]["rotations"].as_array().unwrap().len() {
            let q = |doc: &serde_json::Value| {
                QuatF64::from_array(serde_json::from_value(doc["tracks"][t]["rotations"][j].clone()).unwrap())
            };
            assert!(q(&gpu).angle_to(q(&reference)) < 1e-5);
        }
    }
}

/// Reads a float32 `.npy` file: shape and data.
fn read_npy(path: &Path) -> (Vec<u64>, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    let shape = npy.shape().to_vec();
    (shape, npy.into_vec::<f32>().unwrap())
}

#[test]
fn eval_npy_in_both_layouts_matches_the_json_output() {
    let dir = tempfile::tempdir().unwrap();
    let mut tracks = sample_tracks();
    tracks[1].sample_times = None;
    let input = write_tracks(dir.path(), &tracks);
    let run = |output: &Path, layout: &str| {
        let out = quatcurve(&[
            "eval",
            "--input",
            &input,
            "--output",
            output.to_str().unwrap(),
            "--samples",
            "6",
            "--derivatives",
            "--layout",
            layout,
            "--device",
            "reference",
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
    };
    let (json, track_npy, frame_npy) = (dir.path().join("o.json"), dir.path().join("t.npy"), dir.path().join("f.npy"));
    run(&json, "frame");
    run(&track_npy, "track");
    run(&frame_npy, "frame");
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let (track_shape, by_track) = read_npy(&track_npy);
    let (frame_shape, by_frame) = read_npy(&frame_npy);
    assert_eq!(track_shape, [2, 6, 10]);
    assert_eq!(frame_shape, [6, 2, 10]);
    for t in 0..2 {
        for j in 0..6 {
            let q: [f64; 4] = serde_json::from_value(doc["tracks"][t]["rotations"][j].clone()).unwrap();
            let w: [f64; 3] = serde_json::from_value(doc["tracks"][t]["angular_velocity"][j].clone()).unwrap();
            let a: [f64; 3] = serde_json::from_value(doc["tracks"][t]["angular_acceleration"][j].clone()).unwrap();
            let expected: Vec<f32> = q.iter().chain(&w).chain(&a).map(|&v| v as f32).collect();
            assert_eq!(&by_track[(t * 6 + j) * 10..][..10], &expected[..], "track-major track {t} sample {j}");
            assert_eq!(&by_frame[(j * 2 + t) * 10..][..10], &expected[..], "frame-major track {t} sample {j}");
        }
    }
}

#[test]
fn npy_with_unequal_sample_counts_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_tracks(dir.path(), &sample_tracks());
    let output = dir.path().join("out.npy");
    let out = quatcurve(&["eval", "--input", &input, "--output", output.to_str().unwrap(), "--device", "reference"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("same sample count") && stderr(&out).contains("\"spine\""), "{}", stderr(&out));
    assert!(std::fs::read_dir(dir.path()).unwrap().all(|e| e.unwrap().path().extension().unwrap() == "json"));
}

#[test]
fn bench_reports_every_requested_device_as_json() {
    let require_gpu = std::env::var_os("QUATCURVE_REQUIRE_GPU").is_some();
    let out = quatcurve(&["bench", "--tracks", "40", "--samples", "25", "--runs", "1", "--derivatives", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(doc["workload"]["tracks"], 40);
    assert_eq!(doc["workload"]["samples_per_track"], 25);
    assert_eq!([&doc["workload"]["curve"], &doc["workload"]["knots"]], ["bspline-interp", "phantom"], "eval's curve");
    assert_eq!(doc["workload"]["derivatives"], true);
    let results = doc["results"].as_array().unwrap();
    let devices: Vec<&str> = results.iter().map(|r| r["device"].as_str().unwrap()).collect();
    assert_eq!(devices[..2], ["reference", "cpu"]);
    if require_gpu {
        assert!(devices.contains(&"gpu"), "{devices:?}");
    }
    for r in results {
        assert!(r["samples_per_s"].as_f64().unwrap() > 0.0 && r["seconds"].as_f64().unwrap() > 0.0, "{r}");
        assert_eq!(r["samples"], 1000, "the reference slice covers the whole small batch");
        assert_eq!(r["prepared_samples_per_s"].is_f64(), r["device"] != "reference", "{r}");
        assert_eq!(r["roofline_samples_per_s"].is_f64(), r["device"] == "gpu", "{r}");
        // The spread beside the median, and the rate over the reference's on the same work.
        let [low, median, high] = ["seconds_min", "seconds", "seconds_max"].map(|k| r[k].as_f64().unwrap());
        assert!(low <= median && median <= high, "{r}");
        // Prepared's spread too, where it was timed in turns with end to end (one GPU piece
        // here), and a prepared figure below end to end labelled by the two spreads.
        if r["device"] != "reference" {
            let [fastest, slowest] = ["prepared_seconds_min", "prepared_seconds_max"].map(|k| r[k].as_f64().unwrap());
            assert!(fastest <= slowest, "{r}");
            let below = r["prepared_samples_per_s"].as_f64().unwrap() < r["samples_per_s"].as_f64().unwrap();
            let label = r["prepared_below_end_to_end"].as_str();
            let expected = if fastest <= high { "within_spread" } else { "outside_spread" };
            assert_eq!(label, below.then_some(expected), "{r}");
        }
        let reference = results[0]["samples_per_s"].as_f64().unwrap();
        assert!((r["vs_reference"].as_f64().unwrap() - r["samples_per_s"].as_f64().unwrap() / reference).abs() < 1e-9);
    }
    assert!(!doc["host"].as_str().unwrap().is_empty(), "the host's processor named");
    assert!(doc["workload"]["build_keys_per_s"].as_f64().unwrap() > 0.0);
    // A device named explicitly that is not there is a failure, not a skip.
    let out = Command::cargo_bin("quatcurve")
        .unwrap()
        .args(["bench", "--tracks", "4", "--samples", "4", "--devices", "cpu,gpu"])
        .env("WGPU_BACKEND", "metal")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let out = quatcurve(&["bench", "--tracks", "0"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

/// `eval --input .npz|.npy`: the same tracks as JSON give the same output; times shared,
/// per track, or from `--key-rate`; names carried; bad shapes, dtypes and crafted headers are
/// exit 2 naming the array.
#[test]
fn eval_reads_numpy_arrays_like_json() {
    let dir = tempfile::tempdir().unwrap();
    let (tracks, keys) = (3usize, 6usize);
    let rotation = |t: usize, k: usize| {
        QuatF64::exp(Vec3F64::new(0.1 * k as f64, 0.05 * t as f64, 0.2 * (k * t) as f64 % 0.7)).to_array()
    };
    let rotations: Vec<f64> = (0..tracks).flat_map(|t| (0..keys).flat_map(move |k| rotation(t, k))).collect();
    let times: Vec<f64> = (0..keys).map(|k| 0.25 * k as f64 + 0.01 * (k * k) as f64).collect();
    let names = ["hip", "knee", "toe"];
    let name_bytes: Vec<u8> = names
        .iter()
        .flat_map(|n| format!("{n:\0<4}").chars().flat_map(|c| (c as u32).to_le_bytes()).collect::<Vec<_>>())
        .collect();
    let npz = dir.path().join("tracks.npz");
    write_npz(
        &npz,
        &[
            ("rotations", npy_bytes("<f8", &[tracks as u64, keys as u64, 4], &f64_bytes(&rotations))),
            ("times", npy_bytes("<f8", &[keys as u64], &f64_bytes(&times))),
            ("names", npy_bytes("<U4", &[tracks as u64], &name_bytes)),
        ],
    );
    let json_tracks: Vec<Track> = (0..tracks)
        .map(|t| Track {
            name: Some(names[t].into()),
            times: Some(times.clone()),
            ..Track::from_rotations((0..keys).map(|k| rotation(t, k)).collect())
        })
        .collect();
    let json_in = dir.path().join("tracks.json");
    std::fs::write(&json_in, serde_json::to_string(&TrackFile { tracks: json_tracks }).unwrap()).unwrap();
    let eval = |input: &Path, extra: &[&str]| {
        let out = dir.path().join("out.json");
        let result = quatcurve(
            &[
                &[
                    "eval",
                    "--input",
                    input.to_str().unwrap(),
                    "--output",
                    out.to_str().unwrap(),
                    "--samples",
                    "7",
                    "--device",
                    "reference",
                ][..],
                extra,
            ]
            .concat(),
        );
        assert!(result.status.success(), "{}", stderr(&result));
        std::fs::read_to_string(out).unwrap()
    };
    assert_eq!(eval(&npz, &[]), eval(&json_in, &[]), "npz and JSON inputs differ");
    // Per-track times [tracks, keys] equal to the shared ones: same result.
    let per_track: Vec<f64> = (0..tracks).flat_map(|_| times.clone()).collect();
    let npz2 = dir.path().join("per_track.npz");
    write_npz(
        &npz2,
        &[
            ("rotations", npy_bytes("<f8", &[tracks as u64, keys as u64, 4], &f64_bytes(&rotations))),
            ("times", npy_bytes("<f8", &[tracks as u64, keys as u64], &f64_bytes(&per_track))),
            ("names", npy_bytes("<U4", &[tracks as u64], &name_bytes)),
        ],
    );
    assert_eq!(eval(&npz2, &[]), eval(&json_in, &[]));
    // A bare .npy (float32) with --key-rate: keys at k / rate.
    let npy = dir.path().join("rotations.npy");
    let f32_bytes: Vec<u8> = rotations.iter().flat_map(|&v| (v as f32).to_le_bytes()).collect();
    std::fs::write(&npy, npy_bytes("<f4", &[tracks as u64, keys as u64, 4], &f32_bytes)).unwrap();
    let out: serde_json::Value = serde_json::from_str(&eval(&npy, &["--key-rate", "4"])).unwrap();
    assert_eq!(out["tracks"][0]["times"][6], 1.25, "{}", out["tracks"][0]["times"]);

    let rejected = |name: &str, bytes: Vec<u8>, expected: &[&str]| {
        let path = dir.path().join(name);
        if name.ends_with(".npy") {
            std::fs::write(&path, bytes).unwrap();
        } else {
            write_npz(&path, &[("rotations", bytes)]);
        }
        let result = quatcurve(&["eval", "--input", path.to_str().unwrap(), "--device", "reference"]);
        assert_eq!(result.status.code(), Some(2), "{name}: {}", stderr(&result));
        for part in expected {
            assert!(stderr(&result).contains(part), "{name}: lacks {part:?}: {}", stderr(&result));
        }
    };
    rejected(
        "three.npz",
        npy_bytes("<f8", &[2, 2, 3], &f64_bytes(&[0.0; 12])),
        &["rotations: shape [2, 2, 3]; expected [tracks, keys, 4]"],
    );
    rejected(
        "ints.npz",
        npy_bytes("<i4", &[1, 2, 4], &[0; 32]),
        &["rotations: dtype <i4; expected float32 or float64"],
    );
    // A header announcing 10^18 values over 64 bytes of data: refused before any allocation.
    rejected(
        "huge.npy",
        npy_bytes("<f8", &[1_000_000_000, 1_000_000_000, 4], &f64_bytes(&[0.0; 8])),
        &["rotations", "needs", "the file holds"],
    );
    rejected(
        "short.npy",
        npy_bytes("<f8", &[1, 3, 4], &f64_bytes(&[0.0; 8])),
        &["rotations: the data ends after 8 of the 12 values its shape says"],
    );
    let result = quatcurve(&["eval", "--input", npz.to_str().unwrap(), "--key-rate", "-3"]);
    assert_eq!(result.status.code(), Some(2));
}

/// Results computed in f32 (cpu, gpu) print as the shortest decimal of their f32, not as
/// f64 noise; the reference's f64 results keep every digit.
#[test]
fn f32_results_print_as_f32() {
    let text =
        String::from_utf8(quatcurve(&["eval", "--samples", "5", "--derivatives", "--device", "cpu"]).stdout).unwrap();
    let out: serde_json::Value = serde_json::from_str(&text).unwrap();
    let rotations = out["tracks"][1]["rotations"].as_array().unwrap();
    for v in rotations
        .iter()
        .flat_map(|r| r.as_array().unwrap())
        .chain(out["tracks"][1]["angular_velocity"][2].as_array().unwrap())
    {
        // The token is the f32's shortest decimal: printing the f32 gives the same number.
        let v = v.as_f64().unwrap();
        assert_eq!(format!("{}", v as f32).parse::<f64>().unwrap(), v, "{v} is not an f32's shortest decimal");
    }
    let text = String::from_utf8(quatcurve(&["eval", "--samples", "5", "--device", "reference"]).stdout).unwrap();
    let out: serde_json::Value = serde_json::from_str(&text).unwrap();
    let digits = out["tracks"][1]["rotations"][1][0].to_string();
    assert!(digits.len() > 12, "reference results keep f64 digits: {digits}");
}

/// `auto` never fails where `cpu` works: a batch the GPU kernel cannot take (Bezier degree 39,
/// above its 32) runs on the CPU path and the output names it; `--device gpu` refuses it.
#[test]
fn auto_falls_back_to_the_cpu_for_batches_the_gpu_cannot_take() {
    let dir = tempfile::tempdir().unwrap();
    let keys: Vec<[f64; 4]> =
        (0..40).map(|i| QuatF64::exp(Vec3F64::new(0.0, 0.0, 0.05 * f64::from(i))).to_array()).collect();
    let input = dir.path().join("long.json");
    std::fs::write(&input, serde_json::to_string(&TrackFile { tracks: vec![Track::from_rotations(keys)] }).unwrap())
        .unwrap();
    let out = quatcurve(&["eval", "--input", input.to_str().unwrap(), "--curve", "bezier", "--samples", "5"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(doc["device"].as_str().unwrap().starts_with("cpu:"), "{}", doc["device"]);
    if std::env::var_os("QUATCURVE_REQUIRE_GPU").is_some() {
        let out = quatcurve(&[
            "eval",
            "--input",
            input.to_str().unwrap(),
            "--curve",
            "bezier",
            "--samples",
            "5",
            "--device",
            "gpu",
        ]);
        assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
        assert!(stderr(&out).contains("Bezier degree 39 is above the GPU limit of 32"), "{}", stderr(&out));
    }
}

/// `quatcurve analyze ... --json` as a document, the command having succeeded.
fn analyze_json(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["analyze", "--json"];
    all.extend_from_slice(args);
    let out = quatcurve(&all);
    assert!(out.status.success(), "{}", stderr(&out));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn analyze_reports_every_curve_and_track_with_ratios_to_squad() {
    let dir = tempfile::tempdir().unwrap();
    let input = write_tracks(dir.path(), &sample_tracks());
    let doc = analyze_json(&["--input", &input, "--curves", "bspline-interp,squad,hermite", "--inertia", "1,2,3"]);
    let curves = doc["curves"].as_array().unwrap();
    assert_eq!(curves.len(), 3);
    for c in curves {
        let tracks = c["tracks"].as_array().unwrap();
        assert_eq!(tracks.len(), 2);
        assert_eq!(tracks[0]["name"], "hips");
        for field in ["energy", "torque_energy", "max_omega", "max_alpha", "arc_length", "alpha_jump"] {
            assert!(tracks[1][field].as_f64().unwrap() >= 0.0, "{field}");
            let sum: f64 = tracks.iter().map(|t| t[field].as_f64().unwrap()).sum();
            let total = c["total"][field].as_f64().unwrap();
            assert!(
                if field.starts_with("max") || field.ends_with("jump") {
                    total <= sum
                } else {
                    (total - sum).abs() <= 1e-12 * sum
                },
                "{field}"
            );
        }
    }
    let squad = &curves[1];
    assert_eq!(squad["curve"], "squad");
    assert_eq!(squad["ratio_to_squad"]["torque_energy"], 1.0);
    let interp = &curves[0]["ratio_to_squad"]["energy"].as_f64().unwrap();
    let by_hand = curves[0]["total"]["energy"].as_f64().unwrap() / squad["total"]["energy"].as_f64().unwrap();
    assert!((interp - by_hand).abs() < 1e-12);
    // Without squad there is no ratio.
    let alone = analyze_json(&["--input", &input, "--curves", "hermite"]);
    assert!(alone["curves"][0]["ratio_to_squad"].is_null());
}

#[test]
fn analyze_paper_is_deterministic_for_a_seed() {
    let run =
        |seed: &str| analyze_json(&["--paper", "--seed", seed, "--sequences", "6", "--keys", "5", "--step", "0.01"]);
    let (a, b, c) = (run("7"), run("7"), run("8"));
    assert_eq!(a, b);
    assert_ne!(a["regimes"], c["regimes"]);
    let regimes = a["regimes"].as_array().unwrap();
    assert_eq!(regimes.len(), 2);
    for r in regimes {
        let rows = r["curves"].as_array().unwrap();
        assert_eq!(rows[0]["curve"], "squad");
        assert_eq!(rows[0]["torque_ratio_total"], 1.0);
        assert_eq!(r["sequences"].as_u64().unwrap() + r["left_out"].as_u64().unwrap(), 6);
    }
    // The text report states each claim with its verdict.
    let out = quatcurve(&["analyze", "--paper", "--seed", "7", "--sequences", "4", "--keys", "4", "--step", "0.02"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success()
            && text.contains("small variations")
            && text.contains("large variations")
            && text.contains("C2"),
        "{text}"
    );
}

#[test]
fn analyze_plots_decode_and_are_not_blank() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("rates.png");
    let svg = dir.path().join("rates.svg");
    for path in [&png, &svg] {
        let out = quatcurve(&["analyze", "--curves", "squad,bspline-interp", "--plot", path.to_str().unwrap()]);
        assert!(out.status.success(), "{}", stderr(&out));
        assert!(stderr(&out).contains(&format!("wrote {}", path.display())), "{}", stderr(&out));
    }
    let image = image::load_from_memory(&std::fs::read(&png).unwrap()).unwrap().to_rgb8();
    let colored = image.pixels().filter(|p| p.0.iter().max().unwrap() - p.0.iter().min().unwrap() > 60).count();
    assert!(colored > 2000, "only {colored} coloured pixels: the curves are missing");
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(
        text.starts_with("<svg") && text.contains("bspline-interp") && text.matches("<polyline").count() >= 4,
        "{}",
        &text[..200.min(text.len())]
    );
    // Unknown formats and bad options are usage errors naming the option; nothing is written.
    let gif = dir.path().join("rates.gif");
    let out = quatcurve(&["analyze", "--plot", gif.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains(".png or .svg") && !gif.exists(), "{}", stderr(&out));
    for (args, needle) in [
        (&["analyze", "--inertia", "1,2"][..], "--inertia"),
        (&["analyze", "--step", "0"], "step"),
        (&["analyze", "--inertia", "1,-2,3"], "inertia"),
    ] {
        let out = quatcurve(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(stderr(&out).contains(needle), "{args:?}: {}", stderr(&out));
    }
}

#[test]
fn analyze_on_the_gpu_agrees_with_the_reference() {
    if crate::shared_gpu().is_none() {
        return;
    }
    let args = ["--curves", "bspline-interp,hermite,nam-kim", "--inertia", "1,2,3", "--step", "0.002"];
    let run = |device: &str| {
        let mut all = args.to_vec();
        all.extend(["--device", device]);
        analyze_json(&all)
    };
    let (gpu, reference) = (run("gpu"), run("reference"));
    assert!(gpu["device"].as_str().unwrap().starts_with("gpu: "));
    for (c, r) in gpu["curves"].as_array().unwrap().iter().zip(reference["curves"].as_array().unwrap()) {
        for (t, u) in c["tracks"].as_array().unwrap().iter().zip(r["tracks"].as_array().unwrap()) {
            for field in ["energy", "torque_energy", "arc_length", "max_alpha"] {
                let (a, b) = (t[field].as_f64().unwrap(), u[field].as_f64().unwrap());
                assert!(
                    (a - b).abs() <= 1e-3 * b.abs().max(1.0),
                    "{} {} {field}: gpu {a} vs reference {b}",
                    c["curve"],
                    t["name"]
                );
            }
            let (ja, jb, scale) = (
                t["alpha_jump"].as_f64().unwrap(),
                u["alpha_jump"].as_f64().unwrap(),
                u["max_alpha"].as_f64().unwrap(),
            );
            assert!((ja - jb).abs() <= 1e-3 * scale.max(1.0), "{} jump: gpu {ja} vs reference {jb}", c["curve"]);
        }
    }
}

#[test]
fn bench_sweep_covers_long_and_short_batches_of_every_size_and_plots_them() {
    let dir = tempfile::tempdir().unwrap();
    let plot = dir.path().join("sweep.svg");
    let out = quatcurve(&[
        "bench",
        "--sweep",
        "--sweep-max",
        "10000",
        "--devices",
        "cpu",
        "--runs",
        "1",
        "--json",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let points = doc["sweep"].as_array().unwrap();
    let shapes: Vec<(String, u64, u64)> = points
        .iter()
        .map(|p| {
            (
                p["shape"].as_str().unwrap().to_string(),
                p["tracks"].as_u64().unwrap(),
                p["samples_per_track"].as_u64().unwrap(),
            )
        })
        .collect();
    let expected = [("long", 10, 100), ("short", 100, 10), ("long", 10, 1000), ("short", 1000, 10)]
        .map(|(s, t, n)| (s.to_string(), t, n));
    assert_eq!(shapes, expected);
    assert!(points.iter().all(|p| p["device"] == "cpu" && p["samples_per_s"].as_f64().unwrap() > 0.0));
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.contains("cpu short") && svg.contains("<polyline"), "{}", &svg[..200.min(svg.len())]);
    assert!(stderr(&out).contains(&format!("wrote {}", plot.display())), "{}", stderr(&out));
    // --plot belongs to --sweep.
    let out = quatcurve(&["bench", "--plot", plot.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

/// The formats each subcommand reads, by extension: bake and play (and `bench --playback`)
/// through the table of importers, fit through its own list, eval and analyze tracks.
fn formats_read() -> Vec<(&'static str, Vec<String>)> {
    let importers: Vec<String> = quatcurve::formats::source::input_extensions().map(String::from).collect();
    let tracks = ["json", "npz", "npy"].map(String::from).to_vec();
    vec![
        ("bake", importers.clone()),
        ("play", importers.clone()),
        ("bench", importers),
        ("fit", quatcurve::fit::job::FIT_EXTENSIONS.map(String::from).to_vec()),
        ("eval", [tracks.clone(), vec!["qcf".into()]].concat()),
        ("analyze", tracks),
    ]
}

#[test]
fn every_subcommand_s_one_line_help_names_every_format_it_reads() {
    let top = String::from_utf8(quatcurve(&["--help"]).stdout).unwrap().to_lowercase();
    for (command, extensions) in formats_read() {
        let line = top
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{command} ")))
            .unwrap_or_else(|| panic!("no line for {command} in:\n{top}"));
        for extension in &extensions {
            assert!(line.contains(extension.as_str()), "{command}'s help does not name .{extension}: {line}");
        }
    }
}

#[test]
fn every_input_flag_s_help_names_every_format_its_command_reads() {
    for (command, extensions) in formats_read() {
        let flag = if command == "bench" { "--playback" } else { "--input" };
        let help = String::from_utf8(quatcurve(&[command, "--help"]).stdout).unwrap().to_lowercase();
        // The flag's paragraph: its line and the indented lines after it, up to the next flag.
        let mut lines = help.lines().skip_while(|l| !l.trim_start().starts_with(flag));
        let first = lines.next().unwrap_or_else(|| panic!("{command} --help has no {flag}:\n{help}"));
        let paragraph: String = std::iter::once(first)
            .chain(lines.take_while(|l| !l.trim_start().starts_with('-')))
            .collect::<Vec<_>>()
            .join(" ");
        for extension in &extensions {
            assert!(paragraph.contains(extension.as_str()), "{command} {flag} does not name .{extension}: {paragraph}");
        }
    }
}

#[test]
fn play_takes_zero_seconds_as_one_frame_and_refuses_fewer_as_design_says() {
    let Some(data) = crate::bake::data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (fox, out) = (data.join("Fox.glb"), dir.path().join("palettes.npy"));
    let play = |seconds: &str| {
        quatcurve(&["play", "--input", fox.to_str().unwrap(), "--seconds", seconds, "--output", out.to_str().unwrap()])
    };
    let once = play("0");
    assert!(once.status.success(), "{}", stderr(&once));
    assert_eq!(crate::bake::read_npy(&out).0[0], 1, "one frame");
    std::fs::remove_file(&out).unwrap();
    let refused = play("-1");
    assert_eq!(refused.status.code(), Some(2), "{}", stderr(&refused));
    assert!(!out.exists(), "nothing written");
}
