//! The programs compiled on a device: a compute pipeline with its bind group layout, built
//! from naga's reflection of the WGSL ([`quatcurve_shader`]) so binding numbers and access
//! modes are written once, in the shader.

use crate::error::{GpuError, ResourceError};

/// A compute program compiled on a device: its pipeline, bind group layout, buffers by name
/// and workgroup width. The evaluator keeps the forward-kinematics and mesh-skinning programs
/// in one each, built on first use ([`super::fk`], [`super::skinning`]) by
/// [`super::GpuContext::compile`].
pub(crate) struct Compiled {
    pub(crate) pipeline: wgpu::ComputePipeline,
    pub(crate) layout: wgpu::BindGroupLayout,
    /// The program's buffers by name (binding numbers read from the shader).
    pub(crate) resources: Resources,
    pub(crate) workgroup_size: u32,
}

impl Compiled {
    /// The bind group of `buffers`, each named as the shader names its variable.
    pub(crate) fn bind_group(
        &self,
        device: &wgpu::Device,
        label: &str,
        buffers: &[(&str, &wgpu::Buffer)],
    ) -> Result<wgpu::BindGroup, GpuError> {
        let entries = buffers
            .iter()
            .map(|&(name, buffer)| {
                Ok(wgpu::BindGroupEntry {
                    binding: self.resources.binding(name)?,
                    resource: buffer.as_entire_binding(),
                })
            })
            .collect::<Result<Vec<_>, GpuError>>()?;
        Ok(device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &self.layout,
            entries: &entries,
        }))
    }
}

/// A program's buffers as naga reflects them: every module-scope variable with a `@binding`,
/// by name, with the bind group layout entry its address space implies. The host builds its
/// layouts and bind groups from this, so binding numbers and access modes are written once, in
/// the shader.
#[derive(Clone, Debug)]
pub struct Resources {
    /// `(variable name, layout entry)`, by binding number.
    entries: Vec<(String, wgpu::BindGroupLayoutEntry)>,
}

impl Resources {
    /// Reads the resources of `module`.
    ///
    /// # Errors
    /// A resource outside group 0, unnamed, or not a uniform or storage buffer.
    pub fn of(module: &naga::Module) -> Result<Self, ResourceError> {
        let mut entries = Vec::new();
        for (_, var) in module.global_variables.iter() {
            let Some(binding) = &var.binding else { continue };
            let name = var.name.clone().ok_or(ResourceError::Unnamed { binding: binding.binding })?;
            if binding.group != 0 {
                return Err(ResourceError::Group { name, group: binding.group });
            }
            let ty = match var.space {
                naga::AddressSpace::Uniform => wgpu::BufferBindingType::Uniform,
                naga::AddressSpace::Storage { access } => {
                    wgpu::BufferBindingType::Storage { read_only: !access.contains(naga::StorageAccess::STORE) }
                }
                other => return Err(ResourceError::NotBuffer { name, space: format!("{other:?}") }),
            };
            let entry = wgpu::BindGroupLayoutEntry {
                binding: binding.binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
                count: None,
            };
            entries.push((name, entry));
        }
        entries.sort_by_key(|(_, e)| e.binding);
        Ok(Self { entries })
    }

    /// The bind group layout entries, by binding number.
    #[must_use]
    pub fn layout_entries(&self) -> Vec<wgpu::BindGroupLayoutEntry> {
        self.entries.iter().map(|(_, e)| *e).collect()
    }

    /// The binding number of the buffer variable `name`.
    ///
    /// # Errors
    /// When the program has no such buffer.
    pub fn binding(&self, name: &str) -> Result<u32, ResourceError> {
        self.entries
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, e)| e.binding)
            .ok_or_else(|| ResourceError::Missing { name: name.into() })
    }

    /// `(name, layout entry)` of every buffer, by binding number.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &wgpu::BindGroupLayoutEntry)> {
        self.entries.iter().map(|(n, e)| (n.as_str(), e))
    }
}
