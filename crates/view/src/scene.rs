//! What the viewer's page plays: the bakes a directory holds (found by their sidecars), and
//! for one clip of one bake a scene: the shipped crowd shaders in GLSL ES with the names their
//! resources took, and per mesh primitive its vertex inputs (by the locations the WGSL
//! declares), the textures to sample and the uniform blocks' bytes, built from the sidecar's
//! numbers as an engine would build them (the sidecar read through the types that write it).
//! The page itself knows no file format.

use super::files::url_path;
use super::texels::Texels;
use crate::error::ViewError;
use base64::Engine as _;
use naga::ShaderStage;
use quatcurve_bake::image::{Format, Grid};
use quatcurve_bake::player::Player;
use quatcurve_bake::sidecar::{ImageRecord, Sidecar, SidecarClip};
use quatcurve_bake::texture::TextureKind;
use quatcurve_bake::vertex_encoding::Bounds;
use quatcurve_eval::output::{MATRIX_CHANNELS, VERTEX_CHANNELS};
use quatcurve_eval::skeleton;
use quatcurve_formats::gltf::{self, UriPolicy};
use quatcurve_formats::mesh::{self, SkinnedPrimitive};
use quatcurve_shader::{self as shader, Glsl, Language, Program};
use serde::Serialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// How deep under the served directory sidecars are looked for.
pub const SEARCH_DEPTH: usize = 4;

/// Influences per vertex the crowd vertex shader reads (its `joints: vec4u`); a primitive
/// with more keeps its largest weights, renormalized, and the scene says so.
pub const SHADER_INFLUENCES: usize = 4;

/// Frames of a clip skinned on the CPU to find the box a bone-texture crowd moves in.
const BOX_FRAMES: usize = 16;

/// Which shipped vertex shader plays a bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Playback {
    /// `skin_vertex.wgsl` over a `skin-trs` bone texture: GPU skinning of the glTF's mesh.
    Bones,
    /// `vertex_texture_vertex.wgsl` over a `--texture vertex` bake and its mesh file.
    Vertex,
}

impl Playback {
    /// How a bake of `texture` in `format` plays, or every reason it cannot (the view
    /// player's, [`Player::View`]).
    fn of(texture: &str, format: &str) -> Result<Self, ViewError> {
        let (kind, file) = (texture.parse::<TextureKind>()?, format.parse::<Format>()?);
        let refusals = Player::View.refusals(kind, file);
        if !refusals.is_empty() {
            return Err(ViewError::NotPlayable(refusals));
        }
        Ok(if kind == TextureKind::Vertex { Playback::Vertex } else { Playback::Bones })
    }

    fn program(self) -> Program {
        match self {
            Playback::Bones => Program::Bones,
            Playback::Vertex => Program::Vertex,
        }
    }
}

/// One bake in the served directory: its sidecar and whether (and how) the page plays it.
#[derive(Clone, Debug, Serialize)]
pub struct Bake {
    /// The sidecar's path under the directory, as a URL path.
    pub sidecar: String,
    /// The baked source file.
    pub source: String,
    /// The sidecar's `texture` and `format`.
    pub texture: String,
    /// See [`Self::texture`].
    pub format: String,
    /// Its clips.
    pub clips: Vec<Clip>,
    /// How it plays; `None` with [`Self::refusal`] saying why not.
    pub playback: Option<Playback>,
    /// Why the page cannot play it.
    pub refusal: Option<String>,
}

/// A clip as the page offers it.
#[derive(Clone, Debug, Serialize)]
pub struct Clip {
    /// The clip's name.
    pub name: String,
    /// Baked frames, and their rate in Hz (the clip's own).
    pub frames: u64,
    /// See [`Self::frames`].
    pub rate: f64,
    /// A loop: its last frame is its first.
    pub looping: bool,
    /// Seconds from its first frame to its last.
    pub duration: f64,
    /// Its first frame's time on the source's clock (the page's `time` is on it).
    pub start: f64,
}

impl Clip {
    fn of(clip: &SidecarClip) -> Self {
        let frames = clip.frames as u64;
        Self {
            name: clip.name.clone(),
            frames,
            rate: clip.rate,
            looping: clip.looping,
            duration: frames.saturating_sub(1) as f64 / clip.rate,
            start: clip.start,
        }
    }
}

/// The most bakes a listing holds: a directory of a whole motion library lists its first ones
/// by path, and says how many JSON files it did not read.
pub const MAX_LISTED: usize = 1000;

/// The bakes under a directory, as `/api/bakes` lists them.
#[derive(Clone, Debug, Serialize)]
pub struct Listing {
    /// Bakes by sidecar path, at most [`MAX_LISTED`].
    pub bakes: Vec<Bake>,
    /// JSON files past the listed ones, not read.
    pub left_out: usize,
}

/// The bakes under `root`: sidecars up to [`SEARCH_DEPTH`] directories deep, by path, the
/// first [`MAX_LISTED`] of them.
#[must_use]
pub fn bakes(root: &Path) -> Listing {
    let mut found = Vec::new();
    sidecars(root, SEARCH_DEPTH, &mut found);
    found.sort();
    let mut bakes = Vec::new();
    let mut read = 0;
    for path in &found {
        if bakes.len() == MAX_LISTED {
            break;
        }
        read += 1;
        bakes.extend(bake(root, path));
    }
    Listing { bakes, left_out: found.len() - read }
}

/// The bake whose sidecar `path` is, or `None` for a JSON file that is not a sidecar (one
/// that names no texture kind).
fn bake(root: &Path, path: &Path) -> Option<Bake> {
    let sidecar = read_sidecar(path).ok().filter(|s| !s.texture.is_empty())?;
    let format = if sidecar.format.is_empty() { "npy".to_string() } else { sidecar.format };
    let playback = Playback::of(&sidecar.texture, &format);
    Some(Bake {
        sidecar: url_path(root, path),
        source: sidecar.source,
        texture: sidecar.texture,
        format,
        clips: sidecar.clips.iter().map(Clip::of).collect(),
        refusal: playback.as_ref().err().map(ToString::to_string),
        playback: playback.ok(),
    })
}

fn sidecars(dir: &Path, depth: usize, found: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        // Links are not followed: what is found lies under the directory.
        let Ok(kind) = entry.file_type() else { continue };
        let path = entry.path();
        if kind.is_dir() && depth > 0 {
            sidecars(&path, depth - 1, found);
        } else if kind.is_file() && path.extension().is_some_and(|e| e == "json") {
            found.push(path);
        }
    }
}

/// One clip of one bake, ready to draw.
#[derive(Debug, Serialize)]
pub struct Scene {
    /// Which shader plays it.
    pub playback: Playback,
    /// The clip.
    pub clip: Clip,
    /// The crowd vertex shader (`quatcurve shaders --program bones|vertex --lang glsl-es`) and
    /// the viewer's fragment shader, GLSL ES 3.00 generated by naga.
    pub vertex_shader: String,
    /// See [`Self::vertex_shader`].
    pub fragment_shader: String,
    /// The uniform block of the camera (WGSL group 0): one column-major `mat4`.
    pub camera: String,
    /// The per-instance inputs' locations.
    pub instance: InstanceInputs,
    /// The value of `instance_clip` that plays the clip: its index in the textures' layouts
    /// (the sidecar's `layout.clips`).
    pub instance_clip: usize,
    /// One draw per mesh primitive.
    pub draws: Vec<Draw>,
    /// The box the clip's vertices move in (every draw's, at the bone path's sampled frames).
    pub low: [f64; 3],
    /// See [`Self::low`].
    pub high: [f64; 3],
    /// What the page should show the user about this scene (influences dropped, no normals).
    pub notes: Vec<String>,
}

/// Locations of the crowd shaders' per-instance inputs.
#[derive(Debug, Serialize)]
pub struct InstanceInputs {
    /// `instance_offset` (vec3), `instance_clip` (uint), `instance_time` (float).
    pub offset: u32,
    /// See [`Self::offset`].
    pub clip: u32,
    /// See [`Self::offset`].
    pub time: u32,
}

/// One mesh primitive: vertex inputs by location, triangles, and what it binds.
#[derive(Debug, Serialize)]
pub struct Draw {
    /// The primitive, as the sidecar or the bake's messages name it.
    pub name: String,
    /// Vertices.
    pub vertices: usize,
    /// Per-vertex inputs.
    pub attributes: Vec<Attribute>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// Textures: the GLSL sampler and where its texels are.
    pub textures: Vec<TextureBinding>,
    /// Uniform blocks: the GLSL block and its bytes as 32-bit words.
    pub blocks: Vec<BlockBinding>,
    /// The glTF skin whose joints `joints` indexes (bone textures; `None` for vertex textures).
    pub skin: Option<usize>,
}

/// A per-vertex input.
#[derive(Debug, Serialize)]
pub struct Attribute {
    /// The WGSL input's name and location.
    pub name: String,
    /// See [`Self::name`].
    pub location: u32,
    /// Components (1-4).
    pub size: u32,
    /// An unsigned-integer input (`vertexAttribIPointer`), else float.
    pub integer: bool,
    /// `vertices * size` values.
    pub data: Vec<f64>,
}

/// A texture a draw samples.
#[derive(Debug, Serialize)]
pub struct TextureBinding {
    /// The GLSL sampler.
    pub sampler: String,
    /// The `/texels/...` URL of its `f32` RGBA texels.
    pub url: String,
    /// Its size in texels.
    pub width: usize,
    /// See [`Self::width`].
    pub height: usize,
}

/// A uniform block a draw binds.
#[derive(Debug, Serialize)]
pub struct BlockBinding {
    /// The GLSL uniform block.
    pub block: String,
    /// Its std140 bytes as little-endian 32-bit words (floats by their bits).
    pub words: Vec<u32>,
}

/// The shaders of a playback in GLSL ES, and what the host needs to know of them.
struct Shaders {
    vertex: Glsl,
    fragment: Glsl,
    module: naga::Module,
    inputs: Vec<(String, u32)>,
}

impl Shaders {
    fn of(program: Program) -> Result<Self, ViewError> {
        let vertex = shader::glsl(program.files(), program.entry_point(), ShaderStage::Vertex, Language::GlslEs)?;
        let fragment = Program::Fragment;
        let fragment = shader::glsl(fragment.files(), fragment.entry_point(), fragment.stage(), Language::GlslEs)?;
        let (module, _) = shader::parse(program.files())?;
        let inputs = shader::vertex_inputs(&module, program.entry_point())?;
        Ok(Self { vertex, fragment, module, inputs })
    }

    /// The GLSL name of WGSL resource `wgsl`.
    fn name(&self, wgsl: &str) -> Result<String, ViewError> {
        self.vertex
            .bindings
            .iter()
            .find(|b| b.wgsl == wgsl)
            .map(|b| b.glsl.clone())
            .ok_or_else(|| ViewError::NoBinding { wgsl: wgsl.into() })
    }

    fn location(&self, name: &str) -> Result<u32, ViewError> {
        self.inputs
            .iter()
            .find(|(n, _)| n == name)
            .map(|&(_, l)| l)
            .ok_or_else(|| ViewError::NoInput { name: name.into() })
    }

    fn attribute(&self, name: &str, size: u32, integer: bool, data: Vec<f64>) -> Result<Attribute, ViewError> {
        Ok(Attribute { name: name.to_string(), location: self.location(name)?, size, integer, data })
    }

    /// `words` checked to be the size of WGSL struct `name` (std140 and WGSL's uniform layout
    /// agree for these structs: vec4-aligned members, 16-byte array strides).
    fn block(&self, wgsl: &str, name: &str, words: Vec<u32>) -> Result<BlockBinding, ViewError> {
        let span = shader::struct_span(&self.module, name).ok_or_else(|| ViewError::NoStruct { name: name.into() })?;
        if words.len() * 4 != span as usize {
            return Err(ViewError::BlockSize { name: name.into(), span, packed: words.len() * 4 });
        }
        Ok(BlockBinding { block: self.name(wgsl)?, words })
    }
}

/// Clip `clip` of the bake whose sidecar is at `sidecar` (under `root`, canonical).
///
/// # Errors
/// What in the bake the page cannot play, naming the file, clip or primitive.
pub fn scene(root: &Path, sidecar_path: &Path, clip: usize) -> Result<Scene, ViewError> {
    let sidecar = read_sidecar(sidecar_path)?;
    let dir = sidecar_path.parent().unwrap_or(root);
    let playback = Playback::of(&sidecar.texture, &sidecar.format)?;
    let clips = &sidecar.clips;
    let chosen = clips.get(clip).ok_or(ViewError::NoClip { clip, clips: clips.len() })?;
    let shaders = Shaders::of(playback.program())?;
    let mut bake = Assembly {
        root,
        dir,
        sidecar: &sidecar,
        index: clip,
        clip: chosen,
        instance_clip: None,
        shaders: &shaders,
        notes: Vec::new(),
    };
    let (draws, bounds) = match playback {
        Playback::Bones => bake.bones()?,
        Playback::Vertex => bake.vertex()?,
    };
    let camera = shaders
        .vertex
        .bindings
        .iter()
        .find(|b| b.group == 0 && !b.sampler)
        .ok_or(ViewError::Lacks { what: "no camera block" })?;
    Ok(Scene {
        playback,
        clip: Clip::of(chosen),
        vertex_shader: shaders.vertex.text.clone(),
        fragment_shader: shaders.fragment.text.clone(),
        camera: camera.glsl.clone(),
        instance_clip: bake.instance_clip.unwrap_or(0),
        instance: InstanceInputs {
            offset: shaders.location("instance_offset")?,
            clip: shaders.location("instance_clip")?,
            time: shaders.location("instance_time")?,
        },
        draws,
        low: bounds.low,
        high: bounds.high,
        notes: bake.notes,
    })
}

/// One scene being put together.
struct Assembly<'a> {
    root: &'a Path,
    dir: &'a Path,
    sidecar: &'a Sidecar,
    /// The clip: its index in the sidecar, and the index of it in the textures' layouts.
    index: usize,
    clip: &'a SidecarClip,
    instance_clip: Option<usize>,
    shaders: &'a Shaders,
    notes: Vec<String>,
}

impl<'a> Assembly<'a> {
    /// The sidecar's `textures` record of `file`, its grid, and the file's texel URL.
    fn texture(&self, file: &str) -> Result<(&'a ImageRecord, Grid, PathBuf), ViewError> {
        let sidecar: &'a Sidecar = self.sidecar;
        let record = sidecar
            .textures
            .iter()
            .find(|r| r.file == file)
            .ok_or_else(|| ViewError::NoTextureRecord { file: file.into() })?;
        Ok((record, record.grid, self.dir.join(file)))
    }

    fn binding(&self, wgsl: &str, path: &Path, grid: &Grid) -> Result<TextureBinding, ViewError> {
        Ok(TextureBinding {
            sampler: self.shaders.name(wgsl)?,
            url: format!("/texels/{}", url_path(self.root, path)),
            width: grid.width,
            height: grid.height,
        })
    }

    /// The std140 words of `record`'s layout uniform (the sidecar's), after checking that it
    /// holds the scene's clip at the index every draw gives its instances.
    fn layout_words(&mut self, record: &ImageRecord) -> Result<Vec<u32>, ViewError> {
        let file = &record.file;
        let in_file = ViewError::in_file(file);
        let Some(layout) = record.layout.as_ref() else { return Err(in_file(ViewError::NoLayout)) };
        let Some(at) = layout.clips.iter().position(|&c| c == self.index) else {
            return Err(in_file(ViewError::ClipNotInLayout { clip: self.index, held: layout.clips.clone() }));
        };
        match self.instance_clip.replace(at) {
            Some(other) if other != at => return Err(in_file(ViewError::ClipPlaces { clip: self.index, at, other })),
            _ => {}
        }
        let bytes = match base64::engine::general_purpose::STANDARD.decode(&layout.std140) {
            Ok(bytes) => bytes,
            Err(e) => return Err(in_file(e.into())),
        };
        if bytes.len() % 4 != 0 {
            return Err(in_file(ViewError::Std140Words { bytes: bytes.len() }));
        }
        Ok(bytes.chunks_exact(4).map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]])).collect())
    }

    /// Every skinned primitive of the baked glTF, skinned by `bone_texture.wgsl` from its
    /// skin's `skin-trs` texture of the clip.
    fn bones(&mut self) -> Result<(Vec<Draw>, Bounds), ViewError> {
        let baked =
            self.sidecar.baked_file.as_deref().ok_or(ViewError::Lacks { what: "the sidecar names no baked glTF" })?;
        let path = self.dir.join(baked);
        let file = gltf::read(&path, UriPolicy::default()).map_err(|e| ViewError::in_file(baked)(e.into()))?;
        let drawn = mesh::skinned_primitives(&file).map_err(|e| ViewError::in_file(baked)(e.into()))?;
        self.notes.extend(drawn.not_drawn.iter().map(|m| format!("{m}; not drawn")));
        let primitives = drawn.primitives;
        let files = &self.clip.files;
        let mut texels: HashMap<PathBuf, Texels> = HashMap::new();
        let (mut draws, mut corners) = (Vec::new(), Vec::new());
        for p in &primitives {
            if p.mode != 4 {
                self.notes.push(format!("{}: mode {} is not a triangle list; not drawn", p.name, p.mode));
                continue;
            }
            let name = files
                .get(p.skin)
                .ok_or_else(|| ViewError::NoSkinTexture { primitive: p.name.clone(), skin: p.skin })?;
            let (record, grid, image) = self.texture(name)?;
            let remap = remap(record)?;
            let block = self.shaders.block("bone_layout", "BoneLayout", self.layout_words(record)?)?;
            let joints = record.joints;
            if !texels.contains_key(&image) {
                let read = Texels::read(&image).map_err(ViewError::in_file(name))?;
                texels.insert(image.clone(), read);
            }
            corners.extend(self.skinned_box(p, &texels[&image], &grid, &remap, joints)?);
            draws.push(Draw {
                name: p.name.clone(),
                vertices: p.vertices(),
                attributes: self.bone_attributes(p)?,
                indices: p.indices.clone().unwrap_or_else(|| (0..p.vertices() as u32).collect()),
                textures: vec![self.binding("bone_texture", &image, &grid)?],
                blocks: vec![block],
                skin: Some(p.skin),
            });
        }
        let bounds = Bounds::of_positions(corners).ok_or(ViewError::Lacks { what: "no triangles to draw" })?;
        Ok((draws, bounds))
    }

    /// Positions, normals, and the [`SHADER_INFLUENCES`] largest joints and weights.
    fn bone_attributes(&mut self, p: &SkinnedPrimitive) -> Result<Vec<Attribute>, ViewError> {
        let flat = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
        // Without normals, zeros: the fragment shader lights the faces.
        let normals = match &p.bind.normals {
            Some(n) => flat(n),
            None => {
                self.notes.push(format!("{}: no normals; lit by its faces", p.name));
                vec![0.0; 3 * p.vertices()]
            }
        };
        if p.bind.influences > SHADER_INFLUENCES {
            self.notes.push(format!(
                "{}: {} influences per vertex; the shader reads {SHADER_INFLUENCES}, the largest, renormalized",
                p.name, p.bind.influences
            ));
        }
        let (mut joints, mut weights) = (Vec::new(), Vec::new());
        for v in 0..p.vertices() {
            let range = v * p.bind.influences..(v + 1) * p.bind.influences;
            let mut pairs: Vec<(u32, f64)> =
                p.bind.joints[range.clone()].iter().copied().zip(p.bind.weights[range].iter().copied()).collect();
            pairs.sort_by(|a, b| b.1.total_cmp(&a.1));
            pairs.resize(SHADER_INFLUENCES, (0, 0.0));
            let sum: f64 = pairs.iter().map(|(_, w)| w).sum();
            joints.extend(pairs.iter().map(|&(j, _)| f64::from(j)));
            weights.extend(pairs.iter().map(|&(_, w)| if sum > 0.0 { w / sum } else { 0.0 }));
        }
        Ok(vec![
            self.shaders.attribute("position", 3, false, flat(&p.bind.positions))?,
            self.shaders.attribute("normal", 3, false, normals)?,
            self.shaders.attribute("joints", 4, true, joints)?,
            self.shaders.attribute("weights", 4, false, weights)?,
        ])
    }

    /// The box of `p` skinned on the CPU ([`skeleton::skin`]) at [`BOX_FRAMES`] frames of the
    /// clip, from the texture's own texels.
    fn skinned_box(
        &self,
        p: &SkinnedPrimitive,
        image: &Texels,
        grid: &Grid,
        remap: &[[(f32, f32); 4]; 3],
        joints: usize,
    ) -> Result<Vec<[f64; 3]>, ViewError> {
        let (first_row, frames) = (self.clip.first_row, self.clip.frames.max(1));
        let slots = TextureKind::SkinTrs.texels();
        let mut matrices = Vec::new();
        for f in (0..BOX_FRAMES).map(|i| i * (frames - 1) / (BOX_FRAMES - 1)) {
            for j in 0..joints {
                let mut row = [0.0f32; 10];
                for (t, range) in slots.iter().enumerate() {
                    let (x, y) = grid.texel(first_row + f, j, t);
                    if x >= image.width || y >= image.height {
                        return Err(ViewError::TexelOutside {
                            primitive: p.name.clone(),
                            x,
                            y,
                            width: image.width,
                            height: image.height,
                        });
                    }
                    let texel = image.at((x, y));
                    for (c, r) in range.clone().enumerate() {
                        row[r] = remap[t][c].0 + texel[c] * remap[t][c].1;
                    }
                }
                matrices.extend(skeleton::trs_row(&row).map(|v| v as f32));
            }
        }
        debug_assert_eq!(matrices.len(), BOX_FRAMES * joints * MATRIX_CHANNELS);
        let skinned = skeleton::skin(&p.bind, joints, &matrices);
        Ok(skinned.chunks_exact(VERTEX_CHANNELS).map(|v| [v[0], v[1], v[2]]).collect())
    }

    /// Every primitive of the bake's mesh file, its vertices read from its `.pos` (and
    /// `.nrm`) texture of the clip at its `TEXCOORD_0`.
    fn vertex(&mut self) -> Result<(Vec<Draw>, Bounds), ViewError> {
        let vertex =
            self.sidecar.vertex.as_ref().ok_or(ViewError::Lacks { what: "the sidecar has no `vertex` record" })?;
        let mesh_file = &vertex.mesh_file;
        let bytes = std::fs::read(self.dir.join(mesh_file)).map_err(|e| ViewError::in_file(mesh_file)(e.into()))?;
        let glb = ::gltf::Gltf::from_slice(&bytes).map_err(|e| ViewError::in_file(mesh_file)(e.into()))?;
        let blob = glb
            .blob
            .as_deref()
            .ok_or_else(|| ViewError::in_file(mesh_file)(ViewError::Lacks { what: "no binary chunk" }))?;
        let files = &self.clip.files;
        let ext = self.sidecar.format.parse::<Format>()?.extension();
        let (mut draws, mut corners) = (Vec::new(), Vec::new());
        for p in &vertex.primitives {
            let (name, suffix) = (p.name.clone(), &p.suffix);
            let find = |what: &str| files.iter().find(|f| f.ends_with(&format!("{suffix}.{what}.{ext}")));
            let positions = find("pos").ok_or_else(|| ViewError::NoPositions {
                primitive: name.clone(),
                file: format!("{suffix}.pos.{ext}"),
            })?;
            let (record, grid, pos_path) = self.texture(positions)?;
            let normals = find("nrm").map(|file| self.texture(file)).transpose()?;
            let (Some(low), Some(span)) = (record.low, record.span) else {
                return Err(ViewError::in_file(positions)(ViewError::NoBox));
            };
            corners.push(low);
            corners.push(std::array::from_fn(|i| low[i] + span[i]));
            let words = self.layout_words(record)?;
            let (addresses, indices) =
                mesh_addresses(&glb, blob, p.mesh_in_file).map_err(ViewError::in_file(mesh_file))?;
            // Without normals the layout says so, and the positions stand in for the binding.
            let normal_path = normals.as_ref().map_or(&pos_path, |(_, _, path)| path);
            if normals.is_none() {
                self.notes.push(format!("{name}: no normals; lit by its faces"));
            }
            draws.push(Draw {
                name,
                vertices: addresses.len() / 2,
                attributes: vec![self.shaders.attribute("address", 2, false, addresses)?],
                indices,
                textures: vec![
                    self.binding("vertex_positions", &pos_path, &grid)?,
                    self.binding("vertex_normals", normal_path, &normals.as_ref().map_or(grid, |(_, g, _)| *g))?,
                ],
                blocks: vec![self.shaders.block("vertex_layout", "VertexLayout", words)?],
                skin: None,
            });
        }
        let bounds = Bounds::of_positions(corners).ok_or(ViewError::Lacks { what: "no primitives to draw" })?;
        Ok((draws, bounds))
    }
}

/// `TEXCOORD_0` (flat) and the triangle list of mesh `mesh` of a vertex bake's mesh file, by
/// the glTF crate's reader (as a renderer's importer reads the file).
fn mesh_addresses(glb: &::gltf::Gltf, blob: &[u8], mesh: usize) -> Result<(Vec<f64>, Vec<u32>), ViewError> {
    let mesh = glb.document.meshes().nth(mesh).ok_or(ViewError::NoMesh { mesh })?;
    let primitive = mesh.primitives().next().ok_or(ViewError::Lacks { what: "a mesh without primitives" })?;
    let reader = primitive.reader(|_| Some(blob));
    let addresses: Vec<f64> = reader
        .read_tex_coords(0)
        .ok_or(ViewError::Lacks { what: "a primitive without TEXCOORD_0" })?
        .into_f32()
        .flat_map(|[u, v]| [f64::from(u), f64::from(v)])
        .collect();
    let indices = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..(addresses.len() / 2) as u32).collect(),
    };
    Ok((addresses, indices))
}

/// A bone texture's `(low, span)` per texel slot and channel: PNG16's `remap`, else `(0, 1)`.
fn remap(record: &ImageRecord) -> Result<[[(f32, f32); 4]; 3], ViewError> {
    let mut out = [[(0.0, 1.0); 4]; 3];
    if let Some(remap) = &record.remap {
        if remap.len() < out.len() {
            return Err(ViewError::in_file(&record.file)(ViewError::RemapSlots {
                slots: remap.len(),
                expected: out.len(),
            }));
        }
        for (slot, ranges) in out.iter_mut().zip(remap) {
            for (pair, &[lo, hi]) in slot.iter_mut().zip(ranges) {
                *pair = (lo, (f64::from(hi) - f64::from(lo)) as f32);
            }
        }
    }
    Ok(out)
}

pub(crate) fn read_sidecar(path: &Path) -> Result<Sidecar, ViewError> {
    let in_file = |e: ViewError| ViewError::in_file(path.display())(e);
    let text = std::fs::read_to_string(path).map_err(|e| in_file(e.into()))?;
    serde_json::from_str(&text).map_err(|e| in_file(e.into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_listing_holds_at_most_its_limit_and_counts_what_it_left_unread() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("0-manifest.json"), r#"{"inputs": []}"#).unwrap();
        let sidecar = r#"{"texture": "vertex", "format": "npy", "clips": []}"#;
        for k in 0..MAX_LISTED + 2 {
            std::fs::write(dir.path().join(format!("{k:05}.json")), sidecar).unwrap();
        }
        let listing = bakes(dir.path());
        assert_eq!((listing.bakes.len(), listing.left_out), (MAX_LISTED, 2));
        assert_eq!(listing.bakes[0].sidecar, "00000.json");
        let refusal = listing.bakes[0].refusal.as_deref().unwrap();
        assert_eq!(refusal, "view reads exr or png16 files, not npy; bake for player view");
    }

    #[test]
    fn a_bake_the_page_cannot_play_is_refused_with_every_reason_at_once() {
        let refused = Playback::of("local", "npy").unwrap_err().to_string();
        assert_eq!(
            refused,
            "view plays skin-trs or vertex textures, not local; view reads exr or png16 files, not npy; bake for \
             player view"
        );
        assert_eq!(Playback::of("skin-trs", "png16").unwrap(), Playback::Bones);
        assert_eq!(Playback::of("vertex", "exr").unwrap(), Playback::Vertex);
    }
}
