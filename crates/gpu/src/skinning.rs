//! Linear blend skinning on the GPU for vertex textures (`shaders/skin_mesh.wgsl`), the twin of
//! [`quatcurve_eval::skeleton::skin`]: bind-space vertices, their influences and skinning matrices
//! `[frames, joints, 12]` in, skinned vertices `[frames, vertices, 6]` out. Frames are split
//! into chunks whose matrices and output each fit a storage binding.

use super::context::{ErrorScope, GpuContext};
use super::program::Compiled;
use crate::error::{GpuError, JobError};
use quatcurve_eval::output::{MATRIX_CHANNELS, VERTEX_CHANNELS};
use quatcurve_eval::skeleton::SkinnedMesh;
use quatcurve_shader as shader;
use wgpu::util::DeviceExt;

/// Host twin of WGSL's `SkinMeshJob` (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SkinMeshJob {
    /// Vertices of the primitive.
    pub vertices: u32,
    /// Frames in the chunk.
    pub frames: u32,
    /// Influences per vertex.
    pub influences: u32,
    /// Joints of the skin (matrices per frame).
    pub joints: u32,
    /// Invocations per row of the dispatch grid.
    pub row: u32,
    /// Padding to 32 bytes.
    pub pad: [u32; 3],
}

/// A mesh primitive ready to skin: bind-space vertices and their influences, in the shader's
/// layout.
#[derive(Clone, Debug, PartialEq)]
pub struct BindMesh {
    /// `[vertices, 6]`: position, normal (zero when the mesh has none).
    pub vertices: Vec<f32>,
    /// Influences per vertex.
    pub influences: usize,
    /// Per vertex, `influences` pairs: joint index, weight's bits.
    pub pairs: Vec<u32>,
}

impl BindMesh {
    /// `mesh` in the shader's layout.
    #[must_use]
    pub fn of(mesh: &SkinnedMesh) -> Self {
        let normals = mesh.normals.as_deref();
        let vertices = (0..mesh.vertices())
            .flat_map(|v| {
                let n = normals.map_or([0.0; 3], |n| n[v]);
                let p = mesh.positions[v];
                [p[0], p[1], p[2], n[0], n[1], n[2]].map(|c| c as f32)
            })
            .collect();
        let pairs = mesh.joints.iter().zip(&mesh.weights).flat_map(|(&j, &w)| [j, (w as f32).to_bits()]).collect();
        Self { vertices, influences: mesh.influences, pairs }
    }
}

/// The mesh-skinning program on one device.
pub struct MeshSkinning {
    context: GpuContext,
    program: Compiled,
}

impl std::fmt::Debug for MeshSkinning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshSkinning").field("context", &self.context).finish_non_exhaustive()
    }
}

impl MeshSkinning {
    /// The program compiled on `context`'s device.
    ///
    /// # Errors
    /// [`GpuError::Shader`] or [`GpuError::Device`] when it cannot be built.
    pub fn new(context: &GpuContext) -> Result<Self, GpuError> {
        let (module, _) = shader::skin_mesh_module()?;
        let source = shader::skin_mesh_source();
        let program = context.compile("quatcurve skin mesh", &module, &source, shader::SKIN_MESH_ENTRY_POINT)?;
        Ok(Self { context: context.clone(), program })
    }

    /// `mesh` skinned at every frame of `matrices` (`[frames, joints, 12]`, see the module
    /// docs), in f32.
    ///
    /// # Errors
    /// [`GpuError::Job`] for mismatched inputs, a joint index out of range, or a frame larger
    /// than a binding; device errors.
    pub fn run(&self, mesh: &BindMesh, joints: usize, matrices: &[f32]) -> Result<Vec<f32>, GpuError> {
        let vertices = mesh.vertices.len() / VERTEX_CHANNELS;
        let frame_in = joints * MATRIX_CHANNELS;
        if vertices == 0 || frame_in == 0 || matrices.len() % frame_in != 0 {
            let whole = format!("whole frames of {joints} joints, or the mesh is empty");
            return Err(JobError::NotWhole { what: "matrix floats", len: matrices.len(), whole }.into());
        }
        if mesh.pairs.len() != 2 * vertices * mesh.influences {
            let whole = format!("two per influence of {vertices} vertices");
            return Err(JobError::NotWhole { what: "influence words", len: mesh.pairs.len(), whole }.into());
        }
        if let Some(bad) = mesh.pairs.chunks_exact(2).find(|p| p[0] as usize >= joints) {
            return Err(JobError::JointIndex { index: bad[0], joints }.into());
        }
        let frames = matrices.len() / frame_in;
        let frame_bytes = ((vertices * VERTEX_CHANNELS).max(frame_in) * 4) as u64;
        let limit = self.context.binding_limit();
        if frame_bytes > limit {
            let what = format!("one frame of {vertices} vertices and {joints} joints");
            return Err(JobError::OverBinding { what, bytes: frame_bytes, limit }.into());
        }
        let scope = ErrorScope::push(self.context.device());
        let init = |label: &str, contents: &[u8]| {
            self.context.device().create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let bind = init("quatcurve skin bind", bytemuck::cast_slice(&mesh.vertices));
        let pairs = init("quatcurve skin influences", bytemuck::cast_slice(&mesh.pairs));
        scope.pop()?;
        let mut out = vec![0.0f32; frames * vertices * VERTEX_CHANNELS];
        let per_chunk = ((limit / frame_bytes) as usize).clamp(1, frames);
        for first in (0..frames).step_by(per_chunk) {
            let count = per_chunk.min(frames - first);
            let m = &matrices[first * frame_in..(first + count) * frame_in];
            let o = &mut out[first * vertices * VERTEX_CHANNELS..(first + count) * vertices * VERTEX_CHANNELS];
            self.chunk(&bind, &pairs, mesh.influences, joints, m, o)?;
        }
        Ok(out)
    }

    /// One chunk of whole frames: upload, one dispatch, read back into `out`.
    fn chunk(
        &self,
        bind: &wgpu::Buffer,
        pairs: &wgpu::Buffer,
        influences: usize,
        joints: usize,
        matrices: &[f32],
        out: &mut [f32],
    ) -> Result<(), GpuError> {
        let program = &self.program;
        let device = self.context.device();
        let frames = matrices.len() / (joints * MATRIX_CHANNELS);
        let vertices = out.len() / (frames * VERTEX_CHANNELS);
        let scope = ErrorScope::push(device);
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("quatcurve skin matrices"),
            contents: bytemuck::cast_slice(matrices),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let bytes = (out.len() * 4) as u64;
        let output = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("quatcurve skinned"),
            size: bytes.max(16),
            usage: self.context.output_usage(),
            mapped_at_creation: false,
        });
        let invocations = (vertices * frames) as u64;
        let [x, y] = self.context.grid(invocations.div_ceil(u64::from(program.workgroup_size)))?;
        let job = SkinMeshJob {
            vertices: vertices as u32,
            frames: frames as u32,
            influences: influences as u32,
            joints: joints as u32,
            row: x * program.workgroup_size,
            pad: [0; 3],
        };
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("quatcurve skin job"),
            contents: bytemuck::bytes_of(&job),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let buffers = [
            ("skin_matrices", &input),
            ("skin_bind", bind),
            ("skin_influences", pairs),
            ("skin_out", &output),
            ("skin_job", &uniform),
        ];
        let group = program.bind_group(device, "quatcurve skin mesh", &buffers)?;
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("quatcurve skin mesh") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("quatcurve skin mesh"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&program.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        self.context.queue().submit([encoder.finish()]);
        scope.pop()?;
        self.context.read_back(&output, bytes, |floats| out.copy_from_slice(&floats[..out.len()]))
    }
}
