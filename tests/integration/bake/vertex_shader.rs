//! The shipped vertex-texture library (`shaders/vertex_texture.wgsl`, through its probe entry
//! point) run on a GPU API over real baked EXR atlases and the mesh file's addresses, at
//! every frame and between frames, against the `.npy` bake of the same clips (positions lerped,
//! normals nlerped, loops wrapped); and its crowd vertex shader drawing on a GPU API (its GLSL,
//! GLSL ES and HLSL are checked by glslang with the bone program's, in `shader`).

use super::shader::{bone_texture, naga_module, run_probe, ProbeTextures};
use super::{bake, data_dir, json, read_npy, stderr};
use glam::DVec3;
use quatcurve::shader;
use std::path::Path;

/// One query of `vertex_probe.wgsl` (its `VertexQuery`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Query {
    clip: u32,
    time: f32,
    address: [u32; 2],
}

/// `vertex_texture.wgsl`'s `VertexLayout`: the grid, normals or not, the box, and `clips` as
/// `BoneClip`s from index 0 (the rest of the 64 zero), packed here independently of the bake.
fn layout_bytes(record: &serde_json::Value, clips: &[&serde_json::Value], has_normals: bool) -> Vec<u8> {
    let n = |v: &serde_json::Value| v.as_u64().unwrap() as u32;
    let mut words: Vec<u32> = vec![
        n(&record["frame_width"]),
        n(&record["rows_per_frame"]),
        n(&record["frames_per_column"]),
        u32::from(has_normals),
    ];
    for key in ["low", "span"] {
        words.extend((0..3).map(|c| (record[key][c].as_f64().unwrap() as f32).to_bits()));
        words.push(0);
    }
    for clip in clips {
        let looping = u32::from(clip["loop"].as_bool().unwrap());
        let rate = clip["rate"].as_f64().unwrap() as f32;
        words.extend([n(&clip["first_row"]), n(&clip["frames"]), looping, rate.to_bits()]);
    }
    words.resize(words.len() + (64 - clips.len()) * 4, 0);
    bytemuck::cast_slice(&words).to_vec()
}

#[test]
fn the_layout_and_query_are_laid_out_as_their_wgsl_twins() {
    let (module, _) = naga_module(&shader::vertex_probe_source());
    let find = |name: &str| {
        let (_, ty) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(name)).unwrap();
        let naga::TypeInner::Struct { members, span } = &ty.inner else { panic!("{name} is a struct") };
        (members.iter().map(|m| m.offset).collect::<Vec<u32>>(), *span as usize)
    };
    assert_eq!(find("VertexQuery"), (vec![0, 4, 8], std::mem::size_of::<Query>()));
    let record = serde_json::json!({"frame_width": 1, "rows_per_frame": 1, "frames_per_column": 1,
        "low": [0.0, 0.0, 0.0], "span": [1.0, 1.0, 1.0]});
    let clip = serde_json::json!({"first_row": 0, "frames": 1, "loop": false, "rate": 30.0});
    assert_eq!(find("VertexLayout"), (vec![0, 4, 8, 12, 16, 32, 48], layout_bytes(&record, &[&clip], true).len()));
}

/// Runs `vertex_probe` over one primitive's textures: six floats (position, normal) per query.
fn probe(positions: &Path, normals: Option<&Path>, layout: &[u8], queries: &[Query]) -> Option<Vec<f32>> {
    // Without normals the layout says so, and the positions stand in for the binding.
    let files = vec![positions, normals.unwrap_or(positions)];
    let textures = ProbeTextures { group: 2, files, uniform: layout };
    run_probe(
        &shader::vertex_probe_source(),
        shader::VERTEX_PROBE_ENTRY_POINT,
        &textures,
        bytemuck::cast_slice(queries),
        queries.len(),
        6,
    )
}

#[test]
fn the_vertex_texture_shader_reads_every_frame_and_blends_between_them_as_the_npy_holds() {
    let Some(data) = data_dir() else { return };
    if crate::shared_gpu().is_none() {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let names = ["CesiumMan.glb", "Fox.glb"];
    let inputs: Vec<String> = names.iter().map(|n| data.join(n).display().to_string()).collect();
    for format in ["exr", "npy"] {
        let dir = out.path().join(format);
        let mut args = vec!["--texture", "vertex", "--rate", "30", "--format", format, "--max-texture-size", "1024"];
        if format == "exr" {
            // Every clip of an input in one atlas: clips start at their first_row.
            args.push("--atlas");
        }
        args.extend(["--output", dir.to_str().unwrap(), "--input"]);
        args.extend(inputs.iter().map(String::as_str));
        let result = bake(&args);
        assert!(result.status.success(), "{}", stderr(&result));
    }
    let (mut worst_position, mut worst_normal, mut queried) = (0.0f64, 0.0f64, 0usize);
    for name in names {
        let stem = Path::new(name).file_stem().unwrap().to_str().unwrap();
        let (exr, npy) = (out.path().join("exr"), out.path().join("npy"));
        let sidecar = json(&exr.join(format!("{stem}.json")));
        let raw = json(&npy.join(format!("{stem}.json")));
        let addresses = super::vertex::addresses(&exr.join(format!("{stem}.mesh.glb")));
        for (clip, raw_clip) in sidecar["clips"].as_array().unwrap().iter().zip(raw["clips"].as_array().unwrap()) {
            let (frames, rate) = (clip["frames"].as_u64().unwrap() as usize, clip["rate"].as_f64().unwrap());
            let files: Vec<&str> = clip["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap()).collect();
            for (k, address) in addresses.iter().enumerate() {
                let file =
                    |part: &str| files.iter().find(|f| f.contains(&format!(".mesh{k}.{part}."))).map(|f| exr.join(f));
                let positions = file("pos").unwrap();
                let normals = file("nrm");
                let record = sidecar["textures"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|t| t["file"] == positions.file_name().unwrap().to_str().unwrap())
                    .unwrap();
                let span: Vec<f64> = (0..3).map(|c| record["span"][c].as_f64().unwrap()).collect();
                let diagonal = span.iter().map(|s| s * s).sum::<f64>().sqrt();
                let (shape, rows) = read_npy(&npy.join(raw_clip["files"][k].as_str().unwrap()));
                let vertices = shape[1] as usize;
                let at = |frame: usize, v: usize| -> [f64; 6] {
                    std::array::from_fn(|c| f64::from(rows[(frame * vertices + v) * 6 + c]))
                };
                // Every frame, and half-way between frames; a loop also a period later.
                let mut times: Vec<(f64, usize, f64)> = (0..frames).map(|f| (f as f64 / rate, f, 0.0)).collect();
                times.extend((0..frames - 1).map(|f| ((f as f64 + 0.5) / rate, f, 0.5)));
                if clip["loop"].as_bool().unwrap() {
                    let period = (frames - 1) as f64 / rate;
                    times.extend((0..frames - 1).map(|f| (period + (f as f64 + 0.25) / rate, f, 0.25)));
                }
                let picked: Vec<usize> = (0..vertices).step_by((vertices / 97).max(1)).collect();
                // The sidecar's own layout bytes, held to the packing here.
                let (layout, held) = super::shader::sidecar_layout(record);
                let held_clips: Vec<&serde_json::Value> = held.iter().map(|&c| &sidecar["clips"][c]).collect();
                assert_eq!(layout, layout_bytes(record, &held_clips, normals.is_some()), "{}", record["file"]);
                let index = sidecar["clips"].as_array().unwrap().iter().position(|c| c == clip).unwrap();
                let clip_at = held.iter().position(|&c| c == index).unwrap() as u32;
                let mut queries = Vec::new();
                for &(time, _, _) in &times {
                    for &v in &picked {
                        let [x, y] = address[v].map(|c| c as u32);
                        queries.push(Query { clip: clip_at, time: time as f32, address: [x, y] });
                    }
                }
                let answers = probe(&positions, normals.as_deref(), &layout, &queries).unwrap();
                for (q, (&(time, frame, blend), &v)) in
                    times.iter().flat_map(|t| picked.iter().map(move |v| (t, v))).enumerate()
                {
                    let (a, b) = (at(frame, v), at((frame + 1).min(frames - 1), v));
                    let got = &answers[q * 6..q * 6 + 6];
                    let want: Vec<f64> = (0..3).map(|c| a[c] + (b[c] - a[c]) * blend).collect();
                    let position = (0..3).map(|c| (f64::from(got[c]) - want[c]).powi(2)).sum::<f64>().sqrt() / diagonal;
                    worst_position = worst_position.max(position);
                    let what = format!("{name} clip {} primitive {k} vertex {v} at {time:.4} s", clip["name"]);
                    assert!(position <= 1e-5, "{what}: position off by {position:e} of the diagonal");
                    if normals.is_some() {
                        let n = |r: &[f64; 6]| DVec3::new(r[3], r[4], r[5]);
                        let want = (n(&a) + (n(&b) - n(&a)) * blend).normalize();
                        let got = DVec3::new(f64::from(got[3]), f64::from(got[4]), f64::from(got[5]));
                        let angle = got.angle_between(want);
                        worst_normal = worst_normal.max(angle);
                        assert!(angle <= 1e-4, "{what}: normal off by {angle:e} rad");
                    }
                }
                queried += queries.len();
            }
        }
    }
    eprintln!(
        "vertex_texture.wgsl on the GPU, {queried} queries: positions within {worst_position:.1e} of the diagonal, \
         normals within {worst_normal:.1e} rad of the npy frames, lerped and nlerped"
    );
}

#[test]
fn the_vertex_texture_vertex_shader_draws_on_a_gpu_api() {
    use super::shader::{assert_facing_the_camera, draw, gpu_buffer, identity_camera, show, vertex_group};
    use super::shader::{TEXEL_TEXTURE, UNIFORM};
    let Some(gpu) = crate::shared_gpu() else { return };
    let (device, queue) = (gpu.context().device(), gpu.context().queue());
    // One frame of three vertices whose positions, in the box low (-1, -1, 0.5) span (4, 4, 1),
    // are a triangle over the whole target, each normal +z (octahedral (0.5, 0.5)).
    let positions =
        bone_texture(device, queue, 3, 1, &[[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0]]);
    let normals = bone_texture(device, queue, 3, 1, &[[0.5, 0.5, 0.0, 1.0]; 3]);
    let record = serde_json::json!({"frame_width": 3, "rows_per_frame": 1, "frames_per_column": 1,
        "low": [-1.0, -1.0, 0.5], "span": [4.0, 4.0, 1.0]});
    let clip = serde_json::json!({"first_row": 0, "frames": 1, "loop": false, "rate": 30.0});
    let layout = gpu_buffer(device, &layout_bytes(&record, &[&clip], true), wgpu::BufferUsages::UNIFORM);
    let camera = gpu_buffer(device, &identity_camera(), wgpu::BufferUsages::UNIFORM);
    let (position_view, normal_view) =
        (positions.create_view(&Default::default()), normals.create_view(&Default::default()));
    let group0 = vertex_group(device, &[UNIFORM], &[camera.as_entire_binding()]);
    let group1 = vertex_group(device, &[], &[]);
    let group2 = vertex_group(
        device,
        &[TEXEL_TEXTURE, TEXEL_TEXTURE, UNIFORM],
        &[
            wgpu::BindingResource::TextureView(&position_view),
            wgpu::BindingResource::TextureView(&normal_view),
            layout.as_entire_binding(),
        ],
    );
    // TEXCOORD_0 of the three vertices: texels 0, 1 and 2 of the frame's row.
    let addresses: Vec<u8> = bytemuck::cast_slice(&[0.0f32, 0.0, 1.0, 0.0, 2.0, 0.0]).to_vec();
    let mut instance: Vec<u8> = bytemuck::cast_slice(&[0.0f32; 3]).to_vec();
    instance.extend(bytemuck::cast_slice(&[0u32]));
    instance.extend(bytemuck::cast_slice(&[0.0f32]));
    let attribute = |location, format, offset| wgpu::VertexAttribute { format, offset, shader_location: location };
    use wgpu::VertexFormat as F;
    let per_vertex = [attribute(0, F::Float32x2, 0)];
    let per_instance = [attribute(1, F::Float32x3, 0), attribute(2, F::Uint32, 12), attribute(3, F::Float32, 16)];
    let buffers = [
        (
            wgpu::VertexBufferLayout {
                array_stride: 8,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &per_vertex,
            },
            addresses,
        ),
        (
            wgpu::VertexBufferLayout {
                array_stride: 20,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &per_instance,
            },
            instance,
        ),
    ];
    let source = shader::Program::Vertex.source();
    let groups = [(&group0.0, &group0.1), (&group1.0, &group1.1), (&group2.0, &group2.1)];
    let fragment = show("TexturedOut", "v.normal * 0.5 + 0.5");
    let pixels = draw(&source, &fragment, shader::VERTEX_TEXTURE_ENTRY_POINT, &groups, &buffers, 3).unwrap();
    assert_facing_the_camera(&pixels, "the vertex-texture vertex shader");
}
