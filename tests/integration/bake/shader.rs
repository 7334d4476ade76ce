//! The shipped bone shader (`shaders/bone_texture.wgsl`, through its probe entry point) run on a
//! GPU API over real baked EXR and PNG16 textures, at in-between times, against the curve
//! baked densely on the f64 reference device; with `--max-error-deg` every joint of every clip
//! within the budget. The GLSL and HLSL `quatcurve shaders` generates, checked by glslang.

use super::{bake, data_dir, json, read_npy, stderr};
use quatcurve::formats::source::Source;
use quatcurve::shader;
use serde_json::json;
use std::path::Path;

/// One query of `bone_probe.wgsl` (its `BoneQuery`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Query {
    clip: u32,
    joint: u32,
    time: f32,
    mode: u32,
    joints: [u32; 4],
    weights: [f32; 4],
}

impl Query {
    /// `bone_pose` (mode 0) or `bone_matrix_lerp` (mode 1) of one joint.
    fn of(clip: usize, joint: usize, time: f64, mode: u32) -> Self {
        Self { clip: clip as u32, joint: joint as u32, time: time as f32, mode, joints: [0; 4], weights: [0.0; 4] }
    }
}

#[test]
fn the_query_is_laid_out_as_its_wgsl_twin() {
    let (module, _) = naga_module(&shader::bone_probe_source());
    let (_, ty) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("BoneQuery")).unwrap();
    let naga::TypeInner::Struct { members, span } = &ty.inner else { panic!("BoneQuery is a struct") };
    let offsets: Vec<u32> = members.iter().map(|m| m.offset).collect();
    assert_eq!(
        (offsets, *span as usize),
        (
            vec![0, 4, 8, 12, std::mem::offset_of!(Query, joints) as u32, std::mem::offset_of!(Query, weights) as u32],
            std::mem::size_of::<Query>()
        )
    );
}

/// `BONE_MAX_CLIPS` of bone_texture.wgsl, read by naga.
fn max_clips() -> usize {
    let (module, _) = naga_module(&shader::bone_probe_source());
    shader::constant_u32(&module, "BONE_MAX_CLIPS").expect("bone_texture.wgsl declares BONE_MAX_CLIPS") as usize
}

pub(super) fn naga_module(source: &str) -> (naga::Module, naga::valid::ModuleInfo) {
    let module = naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
    (module, info)
}

/// `BoneLayout`'s bytes (four u32, low and span per texel slot, then `clips` from index 0),
/// packed here from the sidecar's numbers, independently of the bake's packing.
fn layout_bytes(record: &serde_json::Value, clips: &[&serde_json::Value], texels: usize) -> Vec<u8> {
    let n = |k: &str| record[k].as_u64().unwrap() as u32;
    let mut words: Vec<u32> =
        vec![n("texels_per_joint"), n("frame_width"), n("rows_per_frame"), n("frames_per_column")];
    let (mut low, mut span) = (Vec::new(), Vec::new());
    for t in 0..3 {
        for c in 0..4 {
            let (lo, hi) = match record.get("remap") {
                // The sidecar's ranges are f32s.
                Some(remap) if t < texels => {
                    let bound = |k: usize| f64::from(remap[t][c][k].as_f64().unwrap() as f32);
                    (bound(0), bound(1))
                }
                _ => (0.0, 1.0),
            };
            low.push((lo as f32).to_bits());
            span.push(((hi - lo) as f32).to_bits());
        }
    }
    words.extend(low);
    words.extend(span);
    for k in 0..max_clips() {
        match clips.get(k) {
            Some(c) => words.extend([
                c["first_row"].as_u64().unwrap() as u32,
                c["frames"].as_u64().unwrap() as u32,
                u32::from(c["loop"].as_bool().unwrap()),
                (c["rate"].as_f64().unwrap() as f32).to_bits(),
            ]),
            None => words.extend([0; 4]),
        }
    }
    bytemuck::cast_slice(&words).to_vec()
}

/// The bytes of an image record's layout uniform as the sidecar gives them (`layout.std140`),
/// and the clips it holds (sidecar indices, in the layout's order).
pub(super) fn sidecar_layout(record: &serde_json::Value) -> (Vec<u8>, Vec<usize>) {
    use base64::Engine;
    let layout = &record["layout"];
    let file = &record["file"];
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(layout["std140"].as_str().unwrap_or_else(|| panic!("{file}: no layout.std140")))
        .unwrap();
    let clips = layout["clips"].as_array().unwrap().iter().map(|c| c.as_u64().unwrap() as usize).collect();
    (bytes, clips)
}

/// The sidecar's `bone_layout` bytes of `record`, held to [`layout_bytes`] of the clips it says
/// it holds, and the index there of sidecar clip `clip` (an instance's `clip`).
fn bone_layout(sidecar: &serde_json::Value, record: &serde_json::Value, texels: usize, clip: usize) -> (Vec<u8>, u32) {
    let (bytes, held) = sidecar_layout(record);
    let clips: Vec<&serde_json::Value> = held.iter().map(|&c| &sidecar["clips"][c]).collect();
    assert_eq!(bytes, layout_bytes(record, &clips, texels), "{}: the sidecar's std140 bytes", record["file"]);
    let at = held.iter().position(|&c| c == clip).unwrap_or_else(|| panic!("{}: clip {clip} not held", record["file"]));
    (bytes, at as u32)
}

/// An image texture's texels as a renderer samples them: EXR's floats, PNG16's unorm values
/// (the viewer's decoding, which these probes hold to the baked truth).
pub(super) fn texels(path: &Path) -> (u32, u32, Vec<[f32; 4]>) {
    let t = quatcurve::view::texels::Texels::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (t.width as u32, t.height as u32, t.rgba)
}

/// An `rgba32float` texture of `texels`, `width` by `height`, for `bone_texture`.
pub(super) fn bone_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    width: u32,
    height: u32,
    texels: &[[f32; 4]],
) -> wgpu::Texture {
    use wgpu::util::DeviceExt;
    device.create_texture_with_data(
        queue,
        &wgpu::TextureDescriptor {
            label: Some("bone texture"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(texels),
    )
}

/// Runs `bone_probe` over one texture: 12 floats per query.
fn probe(texture: &Path, layout: &[u8], queries: &[Query]) -> Option<Vec<f32>> {
    let textures = ProbeTextures { group: 1, files: vec![texture], uniform: layout };
    run_probe(
        &shader::bone_probe_source(),
        shader::BONE_PROBE_ENTRY_POINT,
        &textures,
        bytemuck::cast_slice(queries),
        queries.len(),
        12,
    )
}

/// What a probe reads besides its queries: image files (bindings 0, 1, ...) and a uniform
/// block after them, in one bind group.
pub(super) struct ProbeTextures<'a> {
    pub(super) group: u32,
    pub(super) files: Vec<&'a Path>,
    pub(super) uniform: &'a [u8],
}

/// Runs compute entry point `entry` of `source` on the shared GPU: `count` queries (their
/// bytes) at group 0 binding 0, `floats_per_query` answers each at binding 1, and `textures`
/// in their group (the groups between them empty). `None` without a GPU; a validation error
/// panics, so a refused probe is never answers of zeros.
pub(super) fn run_probe(
    source: &str,
    entry: &str,
    textures: &ProbeTextures,
    queries: &[u8],
    count: usize,
    floats_per_query: usize,
) -> Option<Vec<f32>> {
    use wgpu::util::DeviceExt;
    let gpu = crate::shared_gpu()?;
    let (device, queue) = (gpu.context().device(), gpu.context().queue());
    // Any validation error (a binding over a limit) fails here, not as answers of zeros.
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let images: Vec<wgpu::Texture> = textures
        .files
        .iter()
        .map(|path| {
            let (width, height, data) = texels(path);
            bone_texture(device, queue, width, height, &data)
        })
        .collect();
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(entry),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let entry_of =
        |binding, ty| wgpu::BindGroupLayoutEntry { binding, visibility: wgpu::ShaderStages::COMPUTE, ty, count: None };
    let buffer = |ty| wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None };
    let texture = wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: false },
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    };
    let layout = |entries: &[wgpu::BindGroupLayoutEntry]| {
        device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: None, entries })
    };
    let io = layout(&[
        entry_of(0, buffer(wgpu::BufferBindingType::Storage { read_only: true })),
        entry_of(1, buffer(wgpu::BufferBindingType::Storage { read_only: false })),
    ]);
    let n = images.len() as u32;
    let mut read_entries: Vec<_> = (0..n).map(|b| entry_of(b, texture)).collect();
    read_entries.push(entry_of(n, buffer(wgpu::BufferBindingType::Uniform)));
    let read_layout = layout(&read_entries);
    let empty = layout(&[]);
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = (0..=textures.group)
        .map(|g| {
            Some(if g == 0 {
                &io
            } else if g == textures.group {
                &read_layout
            } else {
                &empty
            })
        })
        .collect();
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &layouts,
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    let bytes = (count * floats_per_query * 4) as u64;
    let init = |contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents, usage })
    };
    let queries_buffer = init(queries, wgpu::BufferUsages::STORAGE);
    let uniform = init(textures.uniform, wgpu::BufferUsages::UNIFORM);
    let plain = |usage| {
        device.create_buffer(&wgpu::BufferDescriptor { label: None, size: bytes, usage, mapped_at_creation: false })
    };
    let answers = plain(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
    let read = plain(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    let views: Vec<wgpu::TextureView> = images.iter().map(|t| t.create_view(&Default::default())).collect();
    let group = |layout, entries: &[wgpu::BindGroupEntry]| {
        device.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout, entries })
    };
    let io_group = group(
        &io,
        &[
            wgpu::BindGroupEntry { binding: 0, resource: queries_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: answers.as_entire_binding() },
        ],
    );
    let mut read_group_entries: Vec<wgpu::BindGroupEntry> = views
        .iter()
        .enumerate()
        .map(|(b, view)| wgpu::BindGroupEntry { binding: b as u32, resource: wgpu::BindingResource::TextureView(view) })
        .collect();
    read_group_entries.push(wgpu::BindGroupEntry { binding: n, resource: uniform.as_entire_binding() });
    let read_group = group(&read_layout, &read_group_entries);
    let empty_group = group(&empty, &[]);
    let (module_naga, _) = naga_module(source);
    let workgroup = shader::entry_workgroup_size(&module_naga, entry).unwrap();
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        for g in 0..=textures.group {
            let bound = if g == 0 {
                &io_group
            } else if g == textures.group {
                &read_group
            } else {
                &empty_group
            };
            pass.set_bind_group(g, bound, &[]);
        }
        // Within the 65535 groups a dimension allows: callers send at most 4 M queries.
        pass.dispatch_workgroups((count as u32).div_ceil(workgroup), 1, 1);
    }
    encoder.copy_buffer_to_buffer(&answers, 0, &read, 0, bytes);
    queue.submit([encoder.finish()]);
    if let Some(e) = pollster::block_on(scope.pop()) {
        panic!("{}: {entry} was refused: {e}", textures.files[0].display());
    }
    let slice = read.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let out = bytemuck::cast_slice::<u8, f32>(&slice.get_mapped_range().unwrap()).to_vec();
    Some(out)
}

/// Angle in degrees between two quaternions.
fn degrees(a: &[f32], b: &[f32]) -> f64 {
    let dot: f64 = (0..4).map(|i| f64::from(a[i]) * f64::from(b[i])).sum();
    let na: f64 = (0..4).map(|i| f64::from(a[i]).powi(2)).sum::<f64>().sqrt();
    let nb: f64 = (0..4).map(|i| f64::from(b[i]).powi(2)).sum::<f64>().sqrt();
    // clamp, not min: a NaN (an unanswered query) stays NaN.
    (2.0 * (dot.abs() / (na * nb)).clamp(0.0, 1.0).acos()).to_degrees()
}

#[test]
fn a_query_the_shader_leaves_unanswered_is_not_a_small_error() {
    // An answer of zeros (a dispatch that did not run) is NaN degrees off, never within a bound.
    assert!(degrees(&[0.0; 4], &[0.0, 0.0, 0.0, 1.0]).is_nan());
}

/// Worst rotation error (degrees) and where, of the shader over `dir`'s textures of `stem`
/// against `truth` (`[frames, joints, 10]` npy files per clip, baked densely), per clip;
/// `left_out(clip, joint, time)` says which points a budget leaves out.
fn shader_errors(
    dir: &Path,
    stem: &str,
    truth: &Path,
    left_out: &dyn Fn(usize, usize, f64) -> bool,
) -> Option<Vec<(String, f64, f64)>> {
    let sidecar = json(&dir.join(format!("{stem}.json")));
    let dense = json(&truth.join(format!("{stem}.json")));
    let texels = sidecar["texels"].as_array().unwrap().len();
    let mut out = Vec::new();
    for (c, (clip, dense_clip)) in
        sidecar["clips"].as_array().unwrap().iter().zip(dense["clips"].as_array().unwrap()).enumerate()
    {
        for (file, dense_file) in clip["files"].as_array().unwrap().iter().zip(dense_clip["files"].as_array().unwrap())
        {
            let file = file.as_str().unwrap();
            let record = sidecar["textures"].as_array().unwrap().iter().find(|r| r["file"] == file).unwrap();
            let (shape, rows) = read_npy(&truth.join(dense_file.as_str().unwrap()));
            let (frames, joints) = (shape[0] as usize, shape[1] as usize);
            let (layout, at) = bone_layout(&sidecar, record, texels, c);
            let (start, rate) = (dense_clip["start"].as_f64().unwrap(), dense_clip["rate"].as_f64().unwrap());
            let clip_start = clip["start"].as_f64().unwrap();
            let queries: Vec<Query> = (0..frames)
                .flat_map(|f| {
                    let time = (start + f as f64 / rate - clip_start) as f32;
                    (0..joints).map(move |j| Query::of(at as usize, j, f64::from(time), 0))
                })
                .collect();
            // A million queries a dispatch: within 65535 groups of 64, and 48 MB of answers
            // within the default storage binding limit (128 MiB).
            let mut answers = Vec::with_capacity(queries.len() * 12);
            for chunk in queries.chunks(1 << 20) {
                answers.extend(probe(&dir.join(file), &layout, chunk)?);
            }
            let (mut worst, mut at) = (0.0f64, 0.0);
            for (k, (answer, row)) in answers.chunks_exact(12).zip(rows.chunks_exact(10)).enumerate() {
                let e = degrees(&answer[..4], &row[..4]);
                // A query the shader never answered (zeros) is NaN degrees off: never within a bound.
                assert!(e.is_finite(), "{file}: query {k} ({:?}) unanswered", (queries[k].joint, queries[k].time));
                if left_out(c, k % joints, clip_start + f64::from(queries[k].time)) {
                    continue;
                }
                if e > worst {
                    (worst, at) = (e, f64::from(queries[k].time));
                }
            }
            out.push((format!("{stem} '{}' {file}", clip["name"].as_str().unwrap()), worst, at));
        }
    }
    Some(out)
}

fn run_bake(dir: &Path, input: &Path, extra: &[&str]) {
    let mut args = vec!["--input", input.to_str().unwrap(), "--output", dir.to_str().unwrap()];
    args.extend_from_slice(extra);
    let result = bake(&args);
    assert!(result.status.success(), "{}: {}", input.display(), stderr(&result));
}

#[test]
fn the_shader_between_frames_keeps_within_the_budget_the_bake_chose() {
    let Some(data) = data_dir() else { return };
    if crate::shared_gpu().is_none() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    for name in ["CesiumMan.glb", "Fox.glb", "BrainStem.glb", "cmu_131_01.bvh", "cmu_131_03.bvh"] {
        let input = data.join(name);
        let stem = input.file_stem().unwrap().to_string_lossy().into_owned();
        // Every clip as local; the rigid kinds (and PNG16's remap) on the glTF files.
        let kinds: &[(&str, &str)] = if name.ends_with(".bvh") {
            &[("local", "exr")]
        } else {
            &[("local", "exr"), ("model-trs", "png16"), ("skin-trs", "exr")]
        };
        for &(kind, format) in kinds {
            let dir = tmp.path().join(format!("{stem}-{kind}"));
            let args = ["--texture", kind, "--format", format, "--max-error-deg", "0.5", "--device", "cpu"];
            run_bake(&dir, &input, &args);
            let sidecar = json(&dir.join(format!("{stem}.json")));
            // The densest clip's rate times 16: at least 16 points of every clip's frame intervals.
            let densest =
                sidecar["clips"].as_array().unwrap().iter().map(|c| c["rate"].as_f64().unwrap()).fold(0.0, f64::max);
            let truth = tmp.path().join(format!("{stem}-{kind}-truth"));
            let rate = format!("{}", densest * 16.0);
            run_bake(&truth, &input, &["--texture", kind, "--rate", &rate, "--device", "reference"]);
            // CMU's thumbs flip 180 degrees between keys (broken source data the bake warns
            // of): a budget leaves those steps out (DESIGN section 7), and so does this check,
            // for a local texture the flipped joint's own rotation.
            let animation = Source::read(&input, Default::default()).unwrap().animation().clone();
            let broken = |c: usize, joint: usize, time: f64| {
                animation.clips[c].channels.iter().filter(|ch| ch.joint == joint).any(|ch| {
                    let Some((times, _)) = ch.keyed() else { return false };
                    quatcurve::bake::broken_steps(ch).iter().any(|&(i, _)| time > times[i] && time < times[i + 1])
                })
            };
            let errors = shader_errors(&dir, &stem, &truth, &broken).unwrap();
            for (what, worst, at) in errors {
                eprintln!("{kind} {format} {what}: the shader's worst {worst:.4} degrees at {at:.3} s");
                assert!(worst <= 0.5, "{kind} {what}: the shader is {worst} degrees off the curve at {at} s");
                let reported = sidecar["clips"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|c| what.contains(&format!("'{}'", c["name"].as_str().unwrap())))
                    .unwrap()["between_frames"]["rotation"]["value"]
                    .as_f64()
                    .unwrap();
                assert!(
                    (worst - reported).abs() <= 0.02 + 0.1 * reported,
                    "{kind} {what}: shader {worst} against the bake's {reported}"
                );
            }
        }
    }
}

#[test]
fn the_sidecar_names_what_the_skinned_shader_reads_and_draws() {
    let Some(data) = data_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    // CesiumMan has normals and UVs; Fox has UVs and no normals (the crash in three.js).
    for (name, normals) in [("CesiumMan", true), ("Fox", false)] {
        let dir = tmp.path().join(name);
        run_bake(&dir, &data.join(format!("{name}.glb")), &["--texture", "skin-trs", "--format", "exr"]);
        let sidecar = json(&dir.join(format!("{name}.json")));
        let shader = &sidecar["shader"];
        assert_eq!(shader["program"], "bones");
        let primitives = sidecar["primitives"].as_array().unwrap();
        assert_eq!(primitives.len(), 1, "{name}: {primitives:?}");
        assert_eq!((&primitives[0]["normals"], &primitives[0]["texcoords"]), (&json!(normals), &json!(true)), "{name}");
        let inputs: Vec<(&str, u64, &str)> = shader["inputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|i| (i["name"].as_str().unwrap(), i["location"].as_u64().unwrap(), i["from"].as_str().unwrap()))
            .collect();
        assert_eq!(
            inputs,
            [
                ("position", 0, "POSITION"),
                ("normal", 1, "NORMAL"),
                ("joints", 2, "JOINTS_0"),
                ("weights", 3, "WEIGHTS_0"),
                ("instance_offset", 4, "instance"),
                ("instance_clip", 5, "instance"),
                ("instance_time", 6, "instance"),
                ("uv", 7, "TEXCOORD_0"),
            ],
            "{name}"
        );
    }
}

#[test]
fn the_matrix_lerp_is_the_rows_lerped_and_loops_wrap_at_their_period() {
    let Some(data) = data_dir() else { return };
    if crate::shared_gpu().is_none() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let input = data.join("Fox.glb");
    let (exr, npy) = (tmp.path().join("exr"), tmp.path().join("npy"));
    run_bake(&exr, &input, &["--texture", "model", "--format", "exr", "--atlas", "--device", "cpu"]);
    run_bake(&npy, &input, &["--texture", "model", "--atlas", "--device", "cpu"]);
    let sidecar = json(&exr.join("Fox.json"));
    let record = &sidecar["textures"][0];
    let (shape, rows) = read_npy(&npy.join("Fox.npy"));
    let joints = shape[1] as usize;
    let row = |r: usize, j: usize| &rows[(r * joints + j) * 12..(r * joints + j + 1) * 12];
    let mut checked_loops = 0;
    for (c, clip) in sidecar["clips"].as_array().unwrap().iter().enumerate() {
        let (first, frames) = (clip["first_row"].as_u64().unwrap() as usize, clip["frames"].as_u64().unwrap() as usize);
        let rate = clip["rate"].as_f64().unwrap();
        let period = (frames - 1) as f64 / rate;
        // At every frame, half-way to the next, and (for a loop) one period later.
        let mut queries = Vec::new();
        let mut expected: Vec<Vec<f32>> = Vec::new();
        for f in 0..frames - 1 {
            for j in 0..joints {
                let (a, b) = (row(first + f, j), row(first + f + 1, j));
                for (time, want) in [
                    (f as f64 / rate, a.to_vec()),
                    ((f as f64 + 0.5) / rate, a.iter().zip(b).map(|(x, y)| 0.5 * (x + y)).collect()),
                ] {
                    queries.push(Query::of(c, j, time, 1));
                    expected.push(want.clone());
                    if clip["loop"].as_bool().unwrap() {
                        queries.push(Query::of(c, j, time + period, 1));
                        expected.push(want);
                    }
                }
            }
        }
        checked_loops += usize::from(clip["loop"].as_bool().unwrap());
        let (layout, at) = bone_layout(&sidecar, record, 3, c);
        assert_eq!(at as usize, c, "an atlas's layout holds every clip in the sidecar's order");
        let answers = probe(&exr.join(record["file"].as_str().unwrap()), &layout, &queries).unwrap();
        let scale = rows.iter().fold(1.0f32, |a, v| a.max(v.abs()));
        for (k, (answer, want)) in answers.chunks_exact(12).zip(&expected).enumerate() {
            let error = answer.iter().zip(want).map(|(a, w)| (a - w).abs()).fold(0.0f32, f32::max) / scale;
            // f32 times one period later land within about 1e-5 of a frame.
            assert!(
                error <= 2e-4,
                "clip {c} query {k} ({:?}): {answer:?} against {want:?}",
                (queries[k].joint, queries[k].time)
            );
        }
    }
    assert!(checked_loops >= 2, "Fox's Walk and Run loop");
}

#[test]
fn the_skinning_matrix_is_the_weighted_sum_of_the_skin_texture_s_matrices() {
    let Some(data) = data_dir() else { return };
    if crate::shared_gpu().is_none() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let input = data.join("CesiumMan.glb");
    let (trs, matrices) = (tmp.path().join("trs"), tmp.path().join("matrices"));
    run_bake(&trs, &input, &["--texture", "skin-trs", "--format", "exr", "--device", "cpu"]);
    run_bake(&matrices, &input, &["--texture", "skin", "--device", "cpu"]);
    let sidecar = json(&trs.join("CesiumMan.json"));
    let clip = &sidecar["clips"][0];
    let rate = clip["rate"].as_f64().unwrap();
    let (shape, rows) =
        read_npy(&matrices.join(json(&matrices.join("CesiumMan.json"))["clips"][0]["file"].as_str().unwrap()));
    let (frames, joints) = (shape[0] as usize, shape[1] as usize);
    // Vertices bound to four joints each with weights summing to one (SplitMix-like stepping).
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        seed = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        (seed ^ (seed >> 31)).wrapping_mul(0xbf58_476d_1ce4_e5b9) >> 11
    };
    let mut queries = Vec::new();
    let mut expected = Vec::new();
    for f in (0..frames).step_by(7) {
        for _ in 0..20 {
            let bound: [u32; 4] = std::array::from_fn(|_| (next() % joints as u64) as u32);
            let raw: [f32; 4] = std::array::from_fn(|_| (next() % 1000) as f32 + 1.0);
            let total: f32 = raw.iter().sum();
            let weights = raw.map(|w| w / total);
            let mut want = [0.0f32; 12];
            for (j, w) in bound.iter().zip(weights) {
                let at = (f * joints + *j as usize) * 12;
                want.iter_mut().zip(&rows[at..at + 12]).for_each(|(o, v)| *o += w * v);
            }
            queries.push(Query { mode: 2, joints: bound, weights, ..Query::of(0, 0, f as f64 / rate, 2) });
            expected.push(want);
        }
    }
    let record = &sidecar["textures"][0];
    let answers =
        probe(&trs.join(record["file"].as_str().unwrap()), &bone_layout(&sidecar, record, 3, 0).0, &queries).unwrap();
    let scale = rows.iter().fold(1.0f32, |a, v| a.max(v.abs()));
    for (k, (answer, want)) in answers.chunks_exact(12).zip(&expected).enumerate() {
        let error = answer.iter().zip(want).map(|(a, w)| (a - w).abs()).fold(0.0f32, f32::max) / scale;
        assert!(error <= 1e-5, "vertex {k}: {answer:?} against the skin texture's {want:?}");
    }
}

/// A fragment stage `show` that draws `colour`, a WGSL expression of `v`, the vertex shader's
/// output struct `out`: `show(out, "v.normal * 0.5 + 0.5")` shows the normal as a colour.
pub(super) fn show(out: &str, colour: &str) -> (String, &'static str) {
    (format!("@fragment fn show(v: {out}) -> @location(0) vec4f {{ return vec4f({colour}, 1.0); }}"), "show")
}

/// A 4x4 `Rgba8Unorm` image drawn on the shared GPU by vertex entry point `entry` of `source`
/// with `fragment` (its WGSL, appended to `source`, and its entry point), with `groups` bound
/// at their indices and `buffers` (layout, bytes) as vertex buffers 0, 1, ...: `vertices`
/// vertices of one instance. Rows of 256 bytes; `None` without a GPU.
pub(super) fn draw(
    source: &str,
    fragment: &(String, &str),
    entry: &str,
    groups: &[(&wgpu::BindGroupLayout, &wgpu::BindGroup)],
    buffers: &[(wgpu::VertexBufferLayout<'_>, Vec<u8>)],
    vertices: u32,
) -> Option<Vec<u8>> {
    use wgpu::util::DeviceExt;
    let gpu = crate::shared_gpu()?;
    let (device, queue) = (gpu.context().device(), gpu.context().queue());
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let source = format!("{source}\n{}", fragment.0);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(entry),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = groups.iter().map(|(l, _)| Some(*l)).collect();
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &layouts,
        immediate_size: 0,
    });
    let target = wgpu::TextureFormat::Rgba8Unorm;
    let vertex_layouts: Vec<Option<wgpu::VertexBufferLayout<'_>>> =
        buffers.iter().map(|(l, _)| Some(l.clone())).collect();
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(entry),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            buffers: &vertex_layouts,
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some(fragment.1),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState::from(target))],
        }),
        multiview_mask: None,
        cache: None,
    });
    let vertex_buffers: Vec<wgpu::Buffer> = buffers
        .iter()
        .map(|(_, bytes)| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: None,
                contents: bytes,
                usage: wgpu::BufferUsages::VERTEX,
            })
        })
        .collect();
    let size = wgpu::Extent3d { width: 4, height: 4, depth_or_array_layers: 1 };
    let image = device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: target,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let read = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 256 * 4,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let target_view = image.create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: None,
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &target_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store },
            })],
            ..Default::default()
        });
        pass.set_pipeline(&pipeline);
        for (k, (_, group)) in groups.iter().enumerate() {
            pass.set_bind_group(k as u32, *group, &[]);
        }
        for (k, buffer) in vertex_buffers.iter().enumerate() {
            pass.set_vertex_buffer(k as u32, buffer.slice(..));
        }
        pass.draw(0..vertices, 0..1);
    }
    encoder.copy_texture_to_buffer(
        image.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &read,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(256), rows_per_image: None },
        },
        size,
    );
    queue.submit([encoder.finish()]);
    if let Some(e) = pollster::block_on(scope.pop()) {
        panic!("{entry} was refused: {e}");
    }
    let slice = read.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let pixels = slice.get_mapped_range().unwrap().to_vec();
    Some(pixels)
}

/// Every pixel of a [`draw`]n image is the colour of normal +z: (0.5, 0.5, 1).
pub(super) fn assert_facing_the_camera(pixels: &[u8], what: &str) {
    for row in 0..4 {
        for x in 0..4 {
            let p = &pixels[row * 256 + x * 4..row * 256 + x * 4 + 4];
            assert!(
                p[0].abs_diff(128) <= 1 && p[1].abs_diff(128) <= 1 && p[2] == 255,
                "{what}: pixel ({x}, {row}): {p:?}"
            );
        }
    }
}

/// A bind group layout of `entries` visible to the vertex stage, and its group of `resources`.
pub(super) fn vertex_group(
    device: &wgpu::Device,
    entries: &[wgpu::BindingType],
    resources: &[wgpu::BindingResource<'_>],
) -> (wgpu::BindGroupLayout, wgpu::BindGroup) {
    let layout_entries: Vec<wgpu::BindGroupLayoutEntry> = entries
        .iter()
        .enumerate()
        .map(|(k, ty)| wgpu::BindGroupLayoutEntry {
            binding: k as u32,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: *ty,
            count: None,
        })
        .collect();
    let layout =
        device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: None, entries: &layout_entries });
    let group_entries: Vec<wgpu::BindGroupEntry> = resources
        .iter()
        .enumerate()
        .map(|(k, resource)| wgpu::BindGroupEntry { binding: k as u32, resource: resource.clone() })
        .collect();
    let group =
        device.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout: &layout, entries: &group_entries });
    (layout, group)
}

/// A uniform buffer binding's type.
pub(super) const UNIFORM: wgpu::BindingType = wgpu::BindingType::Buffer {
    ty: wgpu::BufferBindingType::Uniform,
    has_dynamic_offset: false,
    min_binding_size: None,
};

/// A texture read texel by texel.
pub(super) const TEXEL_TEXTURE: wgpu::BindingType = wgpu::BindingType::Texture {
    sample_type: wgpu::TextureSampleType::Float { filterable: false },
    view_dimension: wgpu::TextureViewDimension::D2,
    multisampled: false,
};

/// A buffer of `contents` for `usage`, on the shared GPU.
pub(super) fn gpu_buffer(device: &wgpu::Device, contents: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents, usage })
}

/// The identity matrix as a camera's view-projection.
pub(super) fn identity_camera() -> Vec<u8> {
    let identity: [f32; 16] = std::array::from_fn(|i| if i % 5 == 0 { 1.0 } else { 0.0 });
    bytemuck::cast_slice(&identity).to_vec()
}

#[test]
fn the_skinned_vertex_shader_draws_on_a_gpu_api() {
    let Some(gpu) = crate::shared_gpu() else { return };
    let (device, queue) = (gpu.context().device(), gpu.context().queue());
    // One joint at rest (rotation, translation, scale texels) in a one-frame clip; an identity
    // camera; a triangle over the whole target bound to that joint, its normal towards +z.
    let rest: [[f32; 4]; 3] = [[0.0, 0.0, 0.0, 1.0], [0.0; 4], [1.0, 1.0, 1.0, 0.0]];
    let bones = bone_texture(device, queue, 3, 1, &rest);
    let one_frame = serde_json::json!({"first_row": 0, "frames": 1, "loop": false, "rate": 30.0});
    let grid =
        serde_json::json!({"texels_per_joint": 3, "frame_width": 3, "rows_per_frame": 1, "frames_per_column": 1});
    let camera = gpu_buffer(device, &identity_camera(), wgpu::BufferUsages::UNIFORM);
    let bone_layout = gpu_buffer(device, &layout_bytes(&grid, &[&one_frame], 3), wgpu::BufferUsages::UNIFORM);
    // Position, normal (given or zero), joints, weights and a TEXCOORD_0 of (0.25, 0.75).
    let vertices = |normal: [f32; 3]| -> Vec<u8> {
        let mut bytes = Vec::new();
        for [x, y] in [[-1.0f32, -1.0], [3.0, -1.0], [-1.0, 3.0]] {
            bytes.extend(bytemuck::cast_slice(&[x, y, 0.5]));
            bytes.extend(bytemuck::cast_slice(&normal));
            bytes.extend(bytemuck::cast_slice(&[0u32; 4]));
            bytes.extend(bytemuck::cast_slice(&[1.0f32, 0.0, 0.0, 0.0, 0.25, 0.75]));
        }
        bytes
    };
    let mut instance: Vec<u8> = bytemuck::cast_slice(&[0.0f32; 3]).to_vec();
    instance.extend(bytemuck::cast_slice(&[0u32]));
    instance.extend(bytemuck::cast_slice(&[0.0f32]));
    let view = bones.create_view(&Default::default());
    let group0 = vertex_group(device, &[UNIFORM], &[camera.as_entire_binding()]);
    let group1 = vertex_group(
        device,
        &[TEXEL_TEXTURE, UNIFORM],
        &[wgpu::BindingResource::TextureView(&view), bone_layout.as_entire_binding()],
    );
    let attribute = |location, format, offset| wgpu::VertexAttribute { format, offset, shader_location: location };
    use wgpu::VertexFormat as F;
    let per_vertex = [
        attribute(0, F::Float32x3, 0),
        attribute(1, F::Float32x3, 12),
        attribute(2, F::Uint32x4, 24),
        attribute(3, F::Float32x4, 40),
        attribute(7, F::Float32x2, 56),
    ];
    let per_instance = [attribute(4, F::Float32x3, 0), attribute(5, F::Uint32, 12), attribute(6, F::Float32, 16)];
    let buffers = |normal: [f32; 3]| {
        [
            (
                wgpu::VertexBufferLayout {
                    array_stride: 64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &per_vertex,
                },
                vertices(normal),
            ),
            (
                wgpu::VertexBufferLayout {
                    array_stride: 20,
                    step_mode: wgpu::VertexStepMode::Instance,
                    attributes: &per_instance,
                },
                instance.clone(),
            ),
        ]
    };
    let groups = [(&group0.0, &group0.1), (&group1.0, &group1.1)];
    let source = shader::skin_vertex_source();
    let entry = shader::SKIN_VERTEX_ENTRY_POINT;
    let with =
        |fragment: &(String, &str), normal| draw(&source, fragment, entry, &groups, &buffers(normal), 3).unwrap();
    // The normal (0, 0, 1), skinned by the joint at rest, shown as (0.5, 0.5, 1).
    let pixels = with(&show("SkinnedOut", "v.normal * 0.5 + 0.5"), [0.0, 0.0, 1.0]);
    assert_facing_the_camera(&pixels, "the skinned vertex shader");
    // TEXCOORD_0 passes through: (0.25, 0.75) as red and green.
    let pixels = with(&show("SkinnedOut", "vec3f(v.uv, 0.0)"), [0.0, 0.0, 1.0]);
    assert!(pixels[..4].iter().zip([64u8, 191, 0, 255]).all(|(p, w)| p.abs_diff(w) <= 1), "uv: {:?}", &pixels[..4]);
    // The viewer's fragment shader: a mesh without normals (zeros) is lit by its face, which
    // here faces the camera as the normal did, so both draw the same colour.
    let viewer = (shader::VIEWER_FRAGMENT_FILES[0].1.to_string(), shader::VIEWER_FRAGMENT_ENTRY_POINT);
    let lit = with(&viewer, [0.0, 0.0, 1.0]);
    let faceted = with(&viewer, [0.0, 0.0, 0.0]);
    for k in (0..4).flat_map(|row| (0..4).map(move |x| row * 256 + x * 4)) {
        let (a, b) = (&lit[k..k + 4], &faceted[k..k + 4]);
        assert!(a.iter().zip(b).all(|(a, b)| a.abs_diff(*b) <= 2), "lit {a:?}, without normals {b:?}");
        assert!(a[..3].iter().any(|&c| c > 60), "lit: {a:?}");
    }
}

/// glslangValidator, where installed (Debian's glslang-tools; `.ci/run` installs it and sets
/// QUATCURVE_REQUIRE_VALIDATOR, which makes its absence a failure).
fn glslang() -> Option<&'static str> {
    let found =
        std::process::Command::new("glslangValidator").arg("--version").output().is_ok_and(|o| o.status.success());
    if !found {
        assert!(
            std::env::var_os("QUATCURVE_REQUIRE_VALIDATOR").is_none(),
            "glslangValidator is absent and QUATCURVE_REQUIRE_VALIDATOR is set"
        );
        eprintln!("skipped: no glslangValidator");
        return None;
    }
    Some("glslangValidator")
}

#[test]
fn generated_glsl_and_hlsl_compile_with_glslang() {
    let Some(tool) = glslang() else { return };
    let dir = tempfile::tempdir().unwrap();
    // Each program with a function of its library that must be in the output.
    for (program, function) in [
        (shader::Program::Bones, "bone_pose"),
        (shader::Program::Vertex, "vertex_position"),
        (shader::Program::Fragment, "lambert"),
    ] {
        let stage = if program.stage() == naga::ShaderStage::Fragment { "frag" } else { "vert" };
        for (lang, extra) in [
            ("glsl", vec!["-S", stage]),
            ("glsl-es", vec!["-S", stage]),
            ("hlsl", vec!["-D", "-V", "-S", stage, "-e", program.entry_point(), "-o", "/dev/null"]),
        ] {
            let path = dir.path().join(format!("{program}.{lang}"));
            let args = ["shaders", "--program", program.name(), "--lang", lang, "--output", path.to_str().unwrap()];
            let out = assert_cmd::Command::cargo_bin("quatcurve").unwrap().args(args).output().unwrap();
            assert!(out.status.success(), "{program} {lang}: {}", stderr(&out));
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(text.contains(function), "{program} {lang}: the library's {function} is missing");
            let result =
                std::process::Command::new(tool).args(&extra).arg(&path).current_dir(dir.path()).output().unwrap();
            assert!(
                result.status.success(),
                "{program} {lang}: glslang rejects the generated shader:\n{}\n{}",
                String::from_utf8_lossy(&result.stdout),
                text
            );
        }
    }
}

#[test]
fn the_libraries_compile_inside_a_vertex_shader_of_an_engine_s_own() {
    let Some(tool) = glslang() else { return };
    let dir = tempfile::tempdir().unwrap();
    // What an engine writes around `--library`: its own version, inputs and main, which calls
    // the library by its functions and reads its uniforms by their WGSL names.
    for (program, main) in [
        ("bones", "gl_Position = bone_skin_matrix(uint(clip), uvec4(0u), vec4(1.0, 0.0, 0.0, 0.0), 0.5) * vec4(1.0);"),
        ("vertex", "gl_Position = vec4(vertex_position(0u, uvec2(0u), 0.5) + vertex_normal(0u, uvec2(0u), 0.5), 1.0);"),
    ] {
        let out = assert_cmd::Command::cargo_bin("quatcurve")
            .unwrap()
            .args(["shaders", "--program", program, "--lang", "glsl-es", "--library"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{program}: {}", stderr(&out));
        let library = String::from_utf8(out.stdout).unwrap();
        assert!(!library.contains("void main") && !library.contains("#version"), "{program}: {library}");
        let engine = format!(
            "#version 300 es\nprecision highp float;\nprecision highp int;\n{library}\nin float clip;\nvoid main() {{ {main} }}\n"
        );
        let path = dir.path().join(format!("{program}.vert"));
        std::fs::write(&path, &engine).unwrap();
        let result = std::process::Command::new(tool).arg(&path).output().unwrap();
        assert!(
            result.status.success(),
            "{program}: glslang rejects the library in an engine's shader:\n{}\n{engine}",
            String::from_utf8_lossy(&result.stdout)
        );
    }
    let refused = assert_cmd::Command::cargo_bin("quatcurve")
        .unwrap()
        .args(["shaders", "--lang", "hlsl", "--library"])
        .output()
        .unwrap();
    assert_eq!(refused.status.code(), Some(2));
    assert!(stderr(&refused).contains("--library is GLSL ES's"), "{}", stderr(&refused));
}

#[test]
fn a_budget_no_rate_meets_is_exit_2_with_its_words_and_nothing_written() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (fox, out) = (data.join("Fox.glb"), dir.path().join("out"));
    let result = bake(&[
        "--input",
        fox.to_str().unwrap(),
        "--output",
        out.to_str().unwrap(),
        "--max-error-deg",
        "0.01",
        "--max-rate",
        "10",
    ]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    for needle in ["clip 'Survey'", "no rate up to 10 Hz (the highest a budget may choose)", "0.01 degrees", "joint '"]
    {
        assert!(stderr(&result).contains(needle), "{needle:?} missing from: {}", stderr(&result));
    }
    let written: Vec<_> =
        std::fs::read_dir(&out).map(|d| d.flatten().map(|e| e.file_name()).collect()).unwrap_or_default();
    assert!(written.iter().all(|f| !f.to_string_lossy().starts_with("Fox.")), "wrote {written:?}");
}

#[test]
fn budget_flags_a_bake_cannot_take_are_refused_by_their_flags() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fox = data.join("Fox.glb");
    let out = dir.path().join("out");
    let fox_arg = fox.to_str().unwrap();
    let out_arg = out.to_str().unwrap();
    let result = bake(&["--input", fox_arg, "--output", out_arg, "--max-error-deg", "0.5", "--texture", "model"]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("--max-error") && stderr(&result).contains("model-trs"), "{}", stderr(&result));
    let result = bake(&["--input", fox_arg, "--output", out_arg, "--max-error-cm", "-1"]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("--max-error-cm must be a positive number"), "{}", stderr(&result));
    // The library names the option by its own name; the command line shows its flag.
    let result = bake(&["--input", fox_arg, "--output", out_arg, "--max-error-deg", "0.5", "--exact-rate"]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(
        stderr(&result)
            .contains("error: --exact-rate cannot be set with an error budget, which chooses each clip's rate"),
        "{}",
        stderr(&result)
    );
}

/// A position budget is in cm of the file's own unit: a BVH does not say its unit, so the bake
/// needs `--unit-cm` and stops before anything is written without it; with it, the worst
/// position error reported is within the budget.
#[test]
fn a_position_budget_over_a_bvh_needs_its_unit() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let bvh = data.join("cmu_131_01.bvh");
    let out = dir.path().join("out");
    let args = ["--input", bvh.to_str().unwrap(), "--output", out.to_str().unwrap(), "--max-error-cm", "2"];
    let result = bake(&args);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    let message = "--unit-cm is needed for";
    assert!(stderr(&result).contains(message) && stderr(&result).contains("a BVH file"), "{}", stderr(&result));
    assert!(!out.exists(), "nothing written");
    let result = bake(&[&args[..], &["--unit-cm", "5.644", "--texture", "model-trs"]].concat());
    assert!(result.status.success(), "{}", stderr(&result));
    let sidecar = json(&out.join("cmu_131_01.json"));
    let worst = sidecar["clips"][0]["between_frames"]["position"]["value"].as_f64().unwrap();
    assert!(worst > 0.0 && worst <= 2.0, "{worst} cm");
    assert_eq!(sidecar["max_error"]["unit_cm"], 5.644);
}
