//! `quatcurve shaders`: the bone-texture library and its skinned vertex shader, the vertex
//! texture's, and a fragment shader for both, in WGSL (the one source, `shaders/*.wgsl`) or in
//! GLSL and HLSL generated from it by naga's back ends (DESIGN section 7).

use super::{names, print_stdout, Failure};
use clap::Args;
use quatcurve::shader::{self, Language, Program};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ShadersArgs {
    /// The shading language: wgsl (the source), glsl (4.50 core), glsl-es (3.00, WebGL2) or
    /// hlsl (shader model 5.1).
    #[arg(long, default_value = "wgsl", value_parser = names::<Language>())]
    lang: Language,
    /// The program: bones (bone_texture.wgsl and a skinned vertex shader), vertex
    /// (vertex_texture.wgsl over it, and a vertex shader reading a `--texture vertex` bake), or
    /// fragment (a fragment shader for either: a fixed light on the normal they pass at
    /// location 0).
    #[arg(long, default_value = "bones", value_parser = names::<Program>())]
    program: Program,
    /// GLSL ES only: the library's structs, uniforms and functions without the vertex
    /// shader's entry point, to put in a shader of an engine's own (three.js's
    /// onBeforeCompile); uniforms by their WGSL names, a layout block as a uniform struct.
    #[arg(long)]
    library: bool,
    /// Write to this file (atomically) instead of standard output.
    #[arg(long)]
    output: Option<PathBuf>,
}

pub fn run(args: &ShadersArgs) -> Result<(), Failure> {
    let text = match (args.library, args.lang, args.program) {
        (false, ..) => shader::program_in(args.program, args.lang),
        (true, Language::GlslEs, Program::Bones | Program::Vertex) => shader::library(args.program),
        (true, Language::GlslEs, program) => {
            return Err(Failure::Input(format!("--library: the {program} program is no library; take bones or vertex")))
        }
        (true, language, _) => {
            return Err(Failure::Input(format!("--library is GLSL ES's (--lang glsl-es), not {language}'s")))
        }
    }
    .map_err(|e| Failure::Internal(e.to_string()))?;
    match &args.output {
        Some(path) => {
            quatcurve::io::write_atomic(path, |w| w.write_all(text.as_bytes()))
                .map_err(|e| Failure::Input(format!("--output {e}")))?;
            super::wrote(path);
            Ok(())
        }
        None => print_stdout(|w| w.write_all(text.as_bytes())),
    }
}
