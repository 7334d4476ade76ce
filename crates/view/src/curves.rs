//! What the page's WebGPU path plays (DESIGN section 17, "In the browser"): a bake's glTF as
//! curves kept on the GPU, in the bytes and dispatches the native GPU path uses
//! ([`ResidentCurves`]), with the WGSL as it is: the playback-from-curves program, the
//! palette vertex shader and the viewer's fragment shader. Per frame the page writes only the
//! instances' records (`PlayInstance`); everything else here is uploaded once.

use crate::error::ViewError;
use base64::Engine as _;
use quatcurve_anim::curves::CurveChoice;
use quatcurve_anim::loops::LoopMode;
use quatcurve_bake::sidecar::Sidecar;
use quatcurve_formats::gltf::{self, UriPolicy};
use quatcurve_formats::mesh;
use quatcurve_gpu::playback::{FrameBuffer, FrameDispatch, FrameKernels, ResidentCurves, FRAME_BINDINGS};
use quatcurve_play::Playback;
use quatcurve_shader as shader;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// WebGPU's default `maxStorageBufferBindingSize` (128 MiB): every WebGPU device binds this
/// much, so curves packed for it upload on any of them.
pub const WEBGPU_BINDING_LIMIT: u64 = 128 << 20;

/// WebGPU's default `maxComputeWorkgroupsPerDimension`: the grid every device takes.
pub const WEBGPU_MAX_WORKGROUPS: u32 = 65_535;

/// A bake's clips as curves on the GPU, for `instances` instances a frame.
#[derive(Debug, Serialize)]
pub struct CurveScene {
    /// The playback-from-curves program, one WGSL module (`shader::play_curves_source`).
    pub compute_shader: String,
    /// Its override constants: the pose kernel's specialization.
    pub constants: BTreeMap<&'static str, f64>,
    /// Per entry point of a frame, the variables it binds (an automatic layout's).
    pub entries: Vec<Entry>,
    /// The buffers uploaded once.
    pub buffers: Vec<Buffer>,
    /// The frame buffers: which of them (`local`, `model`, `palettes`) each variable binds.
    pub frame_roles: BTreeMap<&'static str, &'static str>,
    /// Floats per instance of each frame buffer.
    pub frame_floats: BTreeMap<&'static str, usize>,
    /// Bytes per instance record (`PlayInstance`).
    pub instance_bytes: usize,
    /// Instances the dispatches are planned for.
    pub instances: usize,
    /// The most instances one frame plays within [`WEBGPU_BINDING_LIMIT`].
    pub max_instances: usize,
    /// A frame's dispatches in order, their uniforms as 32-bit words.
    pub dispatches: Vec<Dispatch>,
    /// The vertex shader over the palettes (`shaders/palette_vertex.wgsl`) and its bindings.
    pub vertex_shader: String,
    /// See [`Self::vertex_shader`].
    pub vertex_entry: &'static str,
    /// See [`Self::vertex_shader`].
    pub vertex_bindings: Vec<Binding>,
    /// The viewer's fragment shader (`shaders/viewer_fragment.wgsl`).
    pub fragment_shader: String,
    /// See [`Self::fragment_shader`].
    pub fragment_entry: &'static str,
    /// Matrices per palette (the played skin's joints).
    pub skin_joints: usize,
    /// The skin played, and every skin of the same joints and inverse bind matrices (its
    /// palettes draw them too): primitives of another skin are not drawn.
    pub skins: Vec<usize>,
    /// The clips on the curves' times.
    pub clips: Vec<CurveClip>,
    /// What the page should show the user.
    pub notes: Vec<String>,
}

/// An entry point and its bindings.
#[derive(Debug, Serialize)]
pub struct Entry {
    /// The entry point.
    pub entry: String,
    /// What it binds.
    pub bindings: Vec<Binding>,
}

/// A bound variable.
#[derive(Debug, Serialize)]
pub struct Binding {
    /// The WGSL variable.
    pub name: String,
    /// Its `@binding` (group 0).
    pub binding: u32,
}

/// A buffer uploaded once.
#[derive(Debug, Serialize)]
pub struct Buffer {
    /// The variable it binds.
    pub name: &'static str,
    /// A uniform buffer, else storage.
    pub uniform: bool,
    /// Its bytes, base64.
    pub base64: String,
}

/// One dispatch of a frame.
#[derive(Debug, Serialize)]
pub struct Dispatch {
    /// The entry point.
    pub entry: &'static str,
    /// Workgroups in x and y.
    pub groups: [u32; 2],
    /// `play_params`.
    pub params: Vec<u32>,
    /// `fk_level`, for a level of forward kinematics.
    pub level: Option<Vec<u32>>,
}

/// A clip as the curves play it.
#[derive(Debug, Serialize)]
pub struct CurveClip {
    /// The clip's name.
    pub name: String,
    /// Its first key on the curves' times (s): a pose at `t` into the clip is at `start + t`.
    pub start: f64,
    /// Its span (s).
    pub duration: f64,
    /// The curves loop (a time past the end wraps on the GPU); else times are held to the span.
    pub looping: bool,
}

impl From<&FrameDispatch> for Dispatch {
    fn from(d: &FrameDispatch) -> Self {
        Self {
            entry: d.entry,
            groups: d.groups,
            params: bytemuck::cast_slice(bytemuck::bytes_of(&d.params)).to_vec(),
            level: d.level.map(|l| bytemuck::cast_slice(bytemuck::bytes_of(&l)).to_vec()),
        }
    }
}

/// The clips of the bake whose sidecar is at `sidecar_path` as curves, planned for
/// `instances` instances.
///
/// # Errors
/// What the curves cannot play, naming the file: no baked glTF, its clips not the bake's, a
/// curve family the sidecar names wrongly, the GPU layout's refusals.
pub fn curve_scene(sidecar_path: &Path, instances: usize) -> Result<CurveScene, ViewError> {
    let sidecar: Sidecar = super::scene::read_sidecar(sidecar_path)?;
    let dir = sidecar_path.parent().unwrap_or(Path::new("."));
    let baked = sidecar.baked_file.as_deref().ok_or(ViewError::Lacks { what: "the sidecar names no baked glTF" })?;
    let in_baked = |e: ViewError| ViewError::in_file(baked)(e);
    let file = gltf::read(&dir.join(baked), UriPolicy::default()).map_err(|e| in_baked(e.into()))?;
    let drawn = mesh::skinned_primitives(&file).map_err(|e| in_baked(e.into()))?;
    let skin = drawn.primitives.iter().find(|p| p.mode == 4).map_or(0, |p| p.skin);
    let all = &file.animation.skins;
    let skins: Vec<usize> = (0..all.len())
        .filter(|&s| all[s].joints == all[skin].joints && all[s].inverse_bind == all[skin].inverse_bind)
        .collect();
    let mut notes: Vec<String> = drawn.not_drawn.iter().map(|m| format!("{m}; not drawn")).collect();
    for p in drawn.primitives.iter().filter(|p| !skins.contains(&p.skin)) {
        notes.push(format!("{}: skin {} is not the one played (skin {skin}); not drawn", p.name, p.skin));
    }
    // The bake's choice (a family with the front ends' defaults for the rest).
    let curve = CurveChoice::from_name(&sidecar.curve)?;
    let playback = Playback::new(file.animation, &curve, LoopMode::Auto, Some(skin)).map_err(|e| in_baked(e.into()))?;
    let names: Vec<&str> = playback.animation().clips.iter().map(|c| c.name.as_str()).collect();
    let baked_names: Vec<&str> = sidecar.clips.iter().map(|c| c.name.as_str()).collect();
    if names != baked_names {
        return Err(in_baked(ViewError::ClipsDiffer {
            curves: names.iter().map(|n| n.to_string()).collect(),
            baked: baked_names.iter().map(|n| n.to_string()).collect(),
        }));
    }
    let clips: Vec<CurveClip> = (0..names.len())
        .map(|c| {
            let [start, end] = playback.animation().clips[c].span();
            CurveClip { name: names[c].to_string(), start, duration: end - start, looping: playback.looping(c) }
        })
        .collect();
    for (clip, baked) in clips.iter().zip(&sidecar.clips) {
        if clip.looping != baked.looping {
            notes.push(format!(
                "{}: the curves loop: {}, the bake's textures: {}",
                clip.name, clip.looping, baked.looping
            ));
        }
    }
    // The baked glTF's samplers are LINEAR: every channel plays on the GPU.
    let curves =
        playback.pose_curves().ok_or_else(|| in_baked(ViewError::Lacks { what: "a channel is not LINEAR" }))?;
    let resident = ResidentCurves::new(&curves, WEBGPU_BINDING_LIMIT).map_err(|e| in_baked(e.into()))?;
    let max_instances = resident.max_frame_instances(WEBGPU_BINDING_LIMIT);
    if instances == 0 || instances > max_instances {
        return Err(ViewError::Instances { instances, max: max_instances });
    }
    let (module, info) = shader::play_curves_module()?;
    let kernels = FrameKernels::of(&module)?;
    let plan = resident.frame_plan(instances, kernels, WEBGPU_MAX_WORKGROUPS)?;
    let bindings = |module: &naga::Module, info: &naga::valid::ModuleInfo, entry: &str| {
        shader::entry_point_bindings(module, info, entry)
            .map(|b| b.into_iter().map(|(name, binding)| Binding { name, binding }).collect::<Vec<_>>())
    };
    let entries = [shader::PLAY_CURVES_ENTRY_POINT, shader::FK_ENTRY_POINT, shader::PLAY_PALETTE_ENTRY_POINT]
        .into_iter()
        .map(|entry| Ok(Entry { entry: entry.to_string(), bindings: bindings(&module, &info, entry)? }))
        .collect::<Result<Vec<_>, ViewError>>()?;
    let (vertex_module, vertex_info) = shader::parse(&shader::PALETTE_VERTEX_FILES)?;
    let base64 = |bytes: &[u8]| base64::engine::general_purpose::STANDARD.encode(bytes);
    Ok(CurveScene {
        compute_shader: shader::play_curves_source(),
        constants: resident.constants.iter().copied().collect(),
        entries,
        buffers: resident
            .buffers
            .iter()
            .map(|b| Buffer { name: b.name, uniform: b.uniform, base64: base64(&b.bytes) })
            .collect(),
        frame_floats: FrameBuffer::ALL.into_iter().map(|b| (b.name(), resident.frame_floats(b))).collect(),
        frame_roles: FRAME_BINDINGS.into_iter().map(|(variable, b)| (variable, b.name())).collect(),
        instance_bytes: std::mem::size_of::<quatcurve_gpu::playback::PlayInstance>(),
        instances,
        max_instances,
        dispatches: plan.iter().map(Dispatch::from).collect(),
        vertex_shader: shader::palette_vertex_source(),
        vertex_entry: shader::PALETTE_VERTEX_ENTRY_POINT,
        vertex_bindings: bindings(&vertex_module, &vertex_info, shader::PALETTE_VERTEX_ENTRY_POINT)?,
        fragment_shader: shader::viewer_fragment_source(),
        fragment_entry: shader::VIEWER_FRAGMENT_ENTRY_POINT,
        skin_joints: resident.skin_joints,
        skins,
        clips,
        notes,
    })
}
