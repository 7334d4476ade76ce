//! `quatcurve shaders`: the bone-texture library and its skinned vertex shader, the vertex
//! texture's, and a fragment shader for both, in WGSL (the one source, `shaders/*.wgsl`) or in
//! GLSL and HLSL generated from it by naga's back ends (DESIGN section 5c).

use super::{names, print_stdout, Failure};
use clap::Args;
use quatcurve::gpu::shader::{self, Language, Program};
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
    /// Write to this file (atomically) instead of standard output.
    #[arg(long, value_name = "FILE")]
    output: Option<PathBuf>,
}

pub fn run(args: &ShadersArgs) -> Result<(), Failure> {
    let text = shader::program_in(args.program, args.lang).map_err(Failure::Internal)?;
    match &args.output {
        Some(path) => quatcurve::io::write_atomic(path, |w| w.write_all(text.as_bytes()))
            .map_err(|e| Failure::Input(format!("--output {e}"))),
        None => print_stdout(|w| w.write_all(text.as_bytes())),
    }
}
