//! Every format quatcurve reads into the animation model (`quatcurve_anim`) and writes baked
//! frames back to: glTF and GLB with their skinned meshes ([`gltf`], [`glb`], [`mesh`], Draco),
//! FBX through ufbx ([`fbx`]), OpenUSD's UsdSkel through openusd ([`usd`]), BVH ([`bvh`]), SMPL-family pose archives ([`smpl`]), the
//! fitted container (`quatcurve_qcf`) and the synthetic crowd ([`crowd`]). [`source`] picks
//! one by the file's extension.

pub mod bvh;
pub mod crowd;
mod draco;
pub mod fbx;
pub mod glb;
mod glb_builder;
pub mod gltf;
pub mod mesh;
pub mod smpl;
pub mod source;
pub mod usd;
