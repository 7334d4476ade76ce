//! A bake on the default options plays every glTF sampler as glTF defines it (LINEAR slerp of
//! rotations and lerp of vectors, STEP held, CUBICSPLINE's cubic Hermite with its tangents, a
//! rotation normalized): a crafted file of each, its local texture held to those formulas
//! written out here in f64; the sidecar names how the source interpolated; a family asked for
//! by name (`--curve`) replaces them all.

use super::{bake, json, read_npy, stderr};
use base64::Engine;
use glam::{DQuat, DVec3};

/// One animated node's sampler: its path, interpolation, key times and output floats (for
/// CUBICSPLINE, in-tangent, value and out-tangent per key).
struct Sampler {
    path: &'static str,
    interpolation: &'static str,
    times: Vec<f32>,
    output: Vec<f32>,
}

/// A glTF of one node per sampler, each animated by its sampler in one clip.
fn gltf(samplers: &[Sampler]) -> String {
    let (mut bytes, mut views, mut accessors) = (Vec::<u8>::new(), Vec::new(), Vec::new());
    let mut add = |floats: &[f32], kind: &str, count: usize, bounds: bool| {
        let offset = bytes.len();
        bytes.extend(floats.iter().flat_map(|v| v.to_le_bytes()));
        views.push(serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": floats.len() * 4}));
        let mut accessor =
            serde_json::json!({"bufferView": views.len() - 1, "componentType": 5126, "count": count, "type": kind});
        if bounds {
            accessor["min"] = serde_json::json!([floats[0]]);
            accessor["max"] = serde_json::json!([floats[floats.len() - 1]]);
        }
        accessors.push(accessor);
        accessors.len() - 1
    };
    let (mut gltf_samplers, mut channels) = (Vec::new(), Vec::new());
    for (node, s) in samplers.iter().enumerate() {
        let input = add(&s.times, "SCALAR", s.times.len(), true);
        let (kind, width) = if s.path == "rotation" { ("VEC4", 4) } else { ("VEC3", 3) };
        let output = add(&s.output, kind, s.output.len() / width, false);
        gltf_samplers.push(serde_json::json!({"input": input, "output": output, "interpolation": s.interpolation}));
        channels.push(serde_json::json!({"sampler": node, "target": {"node": node, "path": s.path}}));
    }
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bytes));
    serde_json::json!({
        "asset": {"version": "2.0"},
        "nodes": (0..samplers.len()).map(|i| serde_json::json!({"name": format!("n{i}")})).collect::<Vec<_>>(),
        "scenes": [{"nodes": (0..samplers.len()).collect::<Vec<_>>()}],
        "buffers": [{"byteLength": bytes.len(), "uri": uri}],
        "bufferViews": views,
        "accessors": accessors,
        "animations": [{"name": "clip", "samplers": gltf_samplers, "channels": channels}]
    })
    .to_string()
}

fn about(axis: DVec3, degrees: f64) -> [f32; 4] {
    DQuat::from_axis_angle(axis.normalize(), degrees.to_radians()).to_array().map(|v| v as f32)
}

/// glTF's cubic Hermite of one component between keys `k` and `k + 1` (per-second tangents).
fn hermite(t: f64, t0: f64, t1: f64, v0: f64, out0: f64, v1: f64, in1: f64) -> f64 {
    let (h, s) = (t1 - t0, (t - t0) / (t1 - t0));
    let (s2, s3) = (s * s, s * s * s);
    (2.0 * s3 - 3.0 * s2 + 1.0) * v0
        + (s3 - 2.0 * s2 + s) * h * out0
        + (-2.0 * s3 + 3.0 * s2) * v1
        + (s3 - s2) * h * in1
}

#[test]
fn the_default_bake_plays_each_gltf_sampler_as_gltf_defines_it() {
    let times = vec![0.0f32, 0.5, 1.25, 2.0];
    let q = [
        about(DVec3::Z, 0.0),
        about(DVec3::new(1.0, 2.0, 0.5), 70.0),
        about(DVec3::new(-1.0, 0.5, 2.0), 150.0),
        about(DVec3::new(0.3, 1.0, -0.4), 20.0),
    ];
    let v: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 2.0, -1.0], [0.5, -3.0, 2.0], [2.0, 1.0, 0.0]];
    // Tangents: arbitrary, per second.
    let rotation_tangents: [[[f32; 4]; 2]; 4] = std::array::from_fn(|k| {
        [[0.3, -0.2, 0.1, 0.05].map(|x| x * k as f32), [-0.1, 0.4, 0.2, -0.3].map(|x| x * (k as f32 - 1.5))]
    });
    let vector_tangents: [[[f32; 3]; 2]; 4] =
        std::array::from_fn(|k| [[1.0, -2.0, 0.5].map(|x| x * k as f32), [-0.5, 3.0, 1.0]]);
    let cubic = |values: &[Vec<f32>], tangents: &[[Vec<f32>; 2]]| -> Vec<f32> {
        values.iter().zip(tangents).flat_map(|(v, [a, b])| [a.clone(), v.clone(), b.clone()].concat()).collect()
    };
    let samplers = [
        Sampler { path: "rotation", interpolation: "LINEAR", times: times.clone(), output: q.concat() },
        Sampler { path: "rotation", interpolation: "STEP", times: times.clone(), output: q.concat() },
        Sampler {
            path: "rotation",
            interpolation: "CUBICSPLINE",
            times: times.clone(),
            output: cubic(&q.map(|x| x.to_vec()), &rotation_tangents.map(|[a, b]| [a.to_vec(), b.to_vec()])),
        },
        Sampler { path: "translation", interpolation: "STEP", times: times.clone(), output: v.concat() },
        Sampler {
            path: "translation",
            interpolation: "CUBICSPLINE",
            times: times.clone(),
            output: cubic(&v.map(|x| x.to_vec()), &vector_tangents.map(|[a, b]| [a.to_vec(), b.to_vec()])),
        },
    ];
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("samplers.gltf");
    std::fs::write(&input, gltf(&samplers)).unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let args = [
            &["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap(), "--rate", "40", "--device", "cpu"],
            extra,
        ]
        .concat();
        let result = bake(&args);
        assert!(result.status.success(), "{}", stderr(&result));
        let sidecar = json(&out.join("samplers.json"));
        let (shape, rows) = read_npy(&out.join(sidecar["clips"][0]["file"].as_str().unwrap()));
        (sidecar, shape, rows)
    };
    let (sidecar, shape, rows) = run("source", &[]);
    assert_eq!(sidecar["curve"], "source");
    assert_eq!(sidecar["interpolation"], serde_json::json!(["CUBICSPLINE", "LINEAR", "STEP"]));
    let (frames, joints) = (shape[0] as usize, shape[1] as usize);
    assert_eq!((frames, joints), (81, 5));
    let row = |rows: &[f32], f: usize, j: usize| -> Vec<f64> {
        rows[(f * joints + j) * 10..][..10].iter().map(|&x| f64::from(x)).collect()
    };
    let t64: Vec<f64> = times.iter().map(|&t| f64::from(t)).collect();
    let (mut worst, mut step_off_slerp) = (0.0f64, 0.0f64);
    for f in 0..frames {
        let t = f as f64 / 40.0;
        let k = t64.iter().rposition(|&x| x <= t).unwrap().min(2);
        let (t0, t1) = (t64[k], t64[k + 1]);
        let quat = |x: [f32; 4]| DQuat::from_array(x.map(f64::from));
        // 4 atan2(|a - b|, |a + b|), hemispheres aligned: exact near zero, where acos is not.
        let angle = |a: DQuat, b: &[f64]| {
            let b = DQuat::from_xyzw(b[0], b[1], b[2], b[3]).normalize();
            let b = if a.dot(b) < 0.0 { -b } else { b };
            4.0 * (a - b).length().atan2((a + b).length())
        };
        // LINEAR: slerp.
        let linear = quat(q[k]).slerp(quat(q[k + 1]), (t - t0) / (t1 - t0));
        worst = worst.max(angle(linear, &row(&rows, f, 0)));
        // STEP: the key at or before t (the last key at the end).
        let held = if t >= t64[3] { 3 } else { k };
        worst = worst.max(angle(quat(q[held]), &row(&rows, f, 1)));
        step_off_slerp = step_off_slerp.max(angle(linear, &row(&rows, f, 1)));
        // CUBICSPLINE: Hermite of the components, normalized.
        let c: Vec<f64> = (0..4)
            .map(|i| {
                let (a, b) = (&rotation_tangents[k], &rotation_tangents[k + 1]);
                hermite(t, t0, t1, q[k][i].into(), a[1][i].into(), q[k + 1][i].into(), b[0][i].into())
            })
            .collect();
        worst = worst.max(angle(DQuat::from_xyzw(c[0], c[1], c[2], c[3]).normalize(), &row(&rows, f, 2)));
        // Vectors: STEP and CUBICSPLINE (relative to the values' size, 3).
        let got = row(&rows, f, 3);
        worst = worst.max((0..3).map(|i| (got[4 + i] - f64::from(v[held][i])).abs() / 3.0).fold(0.0, f64::max));
        let got = row(&rows, f, 4);
        for i in 0..3 {
            let (a, b) = (&vector_tangents[k], &vector_tangents[k + 1]);
            let expected = hermite(t, t0, t1, v[k][i].into(), a[1][i].into(), v[k + 1][i].into(), b[0][i].into());
            worst = worst.max((got[4 + i] - expected).abs() / 3.0);
        }
    }
    eprintln!("every sampler within {worst:.1e} of glTF's formulas; STEP up to {step_off_slerp:.2} rad off slerp");
    assert!(worst < 1e-6, "a frame is {worst} off its sampler's interpolation");
    assert!(step_off_slerp > 0.5, "the STEP channel is no different from slerp");
    // A family by name replaces every sampler's interpolation: the STEP channel slerped.
    let (sidecar, _, slerped) = run("slerp", &["--curve", "slerp"]);
    assert_eq!(sidecar["curve"], "slerp");
    assert!(sidecar.get("interpolation").is_none(), "{sidecar}");
    let off = (0..frames)
        .map(|f| row(&slerped, f, 1))
        .zip((0..frames).map(|f| row(&slerped, f, 0)))
        .map(|(a, b)| a.iter().zip(&b).take(4).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(off < 1e-6, "with --curve slerp, the STEP channel is not the LINEAR one: {off}");
}
