//! The WGSL program without a GPU: naga parses and validates it, and every layout fact the
//! host shares with it (struct offsets, codes, limits, workgroup size) is checked against it.

use quatcurve::gpu::layout::{self, GpuTrack, Params};
use quatcurve::shader;
use quatcurve::{real, Blend, Curve};

#[test]
fn every_shader_file_parses_and_the_program_validates() {
    for (name, text) in shader::FILES {
        assert!(!text.trim().is_empty(), "{name} is empty");
    }
    if let Err(e) = shader::module() {
        panic!("naga rejected the program:\n{e}");
    }
}

#[test]
fn every_shipped_program_translates_to_every_language() {
    use shader::{Language, Program};
    for program in [Program::Bones, Program::Vertex, Program::Fragment] {
        for language in [Language::Wgsl, Language::Glsl, Language::GlslEs, Language::Hlsl] {
            let text = shader::program_in(program, language).unwrap_or_else(|e| panic!("{program} in {language}: {e}"));
            // GLSL names its one entry point main.
            let entry = if matches!(language, Language::Glsl | Language::GlslEs) {
                "void main("
            } else {
                program.entry_point()
            };
            assert!(text.contains(entry), "{program} in {language} lacks {entry}");
        }
    }
}

#[test]
fn the_viewer_fragment_shader_links_to_both_crowd_vertex_shaders_in_glsl_es() {
    use shader::{Language, Program};
    let varyings = |text: &str, qualifier: &str| -> Vec<String> {
        text.lines()
            .filter(|l| l.contains(&format!(" {qualifier} ")) && l.contains("_vs2fs_"))
            .map(|l| l.split_whitespace().last().unwrap().trim_end_matches(';').to_string())
            .collect()
    };
    let fragment = Program::Fragment;
    let fragment = shader::glsl(fragment.files(), fragment.entry_point(), fragment.stage(), Language::GlslEs).unwrap();
    let inputs = varyings(&fragment.text, "in");
    // The normal and the position lit.
    assert_eq!(inputs, ["_vs2fs_location0", "_vs2fs_location1"], "{}", fragment.text);
    for program in [Program::Bones, Program::Vertex] {
        let vertex =
            shader::glsl(program.files(), program.entry_point(), naga::ShaderStage::Vertex, Language::GlslEs).unwrap();
        let outputs = varyings(&vertex.text, "out");
        assert!(inputs.iter().all(|i| outputs.contains(i)), "{program} writes {outputs:?}, not all of {inputs:?}");
    }
}

#[test]
fn shader_program_uses_no_f64() {
    // naga 30 emits invalid SPIR-V for f64 transcendentals, which lavapipe runs silently wrong.
    let (module, _) = shader::module().unwrap();
    for (_, ty) in module.types.iter() {
        let scalar = match &ty.inner {
            naga::TypeInner::Scalar(s) => Some(*s),
            naga::TypeInner::Vector { scalar, .. } | naga::TypeInner::Matrix { scalar, .. } => Some(*scalar),
            _ => None,
        };
        if let Some(s) = scalar {
            assert!(!(s.kind == naga::ScalarKind::Float && s.width == 8), "f64 type in the program: {ty:?}");
        }
    }
}

#[test]
fn workgroup_size_is_read_from_the_shader() {
    let (module, _) = shader::module().unwrap();
    let size = shader::workgroup_size(&module).unwrap();
    // What eval.wgsl declares, read from its text independently of naga.
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/crates/shader/shaders/eval.wgsl")).unwrap();
    let declared: u32 = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("const WORKGROUP_SIZE: u32 = "))
        .and_then(|v| v.trim_end_matches(';').trim_end_matches('u').parse().ok())
        .expect("eval.wgsl declares `const WORKGROUP_SIZE: u32 = N;`");
    assert_eq!(size, declared);
    assert!(text.contains("@workgroup_size(WORKGROUP_SIZE)"), "the entry points take their size from the constant");
}

/// (name, offset) of each field of a naga struct.
fn naga_struct(module: &naga::Module, name: &str) -> (Vec<(String, u32)>, u32) {
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name}"))
        .1;
    match &ty.inner {
        naga::TypeInner::Struct { members, span } => {
            (members.iter().map(|m| (m.name.clone().unwrap(), m.offset)).collect(), *span)
        }
        other => panic!("{name} is not a struct: {other:?}"),
    }
}

macro_rules! rust_layout {
    ($ty:ty, $($field:ident),+ $(,)?) => {
        (vec![$((stringify!($field).to_string(), std::mem::offset_of!($ty, $field) as u32)),+], std::mem::size_of::<$ty>() as u32)
    };
}

#[test]
fn rust_structs_match_naga_layout_of_their_wgsl_twins() {
    let (module, _) = shader::module().unwrap();
    let track = rust_layout!(
        GpuTrack,
        curve,
        order,
        blend,
        flags,
        point_offset,
        point_count,
        coef_offset,
        knot_offset,
        knot_count,
        sample_offset,
        sample_count,
        time_offset,
        start_lo,
        start_hi,
        last_lo,
        last_hi,
        step_whole,
        step_frac_hi,
        step_frac_lo,
        sample_base,
    );
    assert_eq!(naga_struct(&module, "GpuTrack"), track);
    let params = rust_layout!(Params, sample_count, track_count, channels, frame_major, groups_x, pad0, pad1, pad2);
    assert_eq!(naga_struct(&module, "Params"), params);
}

#[test]
fn codes_and_limits_match_the_shader_constants() {
    let (module, _) = shader::module().unwrap();
    let c = |name: &str| shader::constant_u32(&module, name).unwrap_or_else(|| panic!("no constant {name}"));
    for (curve, name) in [
        (Curve::Slerp, "CURVE_SLERP"),
        (Curve::Squad, "CURVE_SQUAD"),
        (Curve::Bezier, "CURVE_BEZIER"),
        (Curve::Hermite, "CURVE_HERMITE"),
        (Curve::NamKim, "CURVE_NAM_KIM"),
        (Curve::BSpline, "CURVE_BSPLINE"),
        (Curve::NormalizedBSpline, "CURVE_NORMALIZED_BSPLINE"),
    ] {
        assert_eq!(layout::curve_code(curve), c(name), "{name}");
    }
    assert_eq!(layout::blend_code(Blend::Quadratic), c("BLEND_QUADRATIC"));
    assert_ne!(layout::blend_code(Blend::Cubic), c("BLEND_QUADRATIC"));
    assert_eq!(layout::ANY_CURVE, c("ANY_CURVE"));
    assert_eq!(layout::BSPLINE_FORMS, c("BSPLINE_FORMS"));
    assert_eq!(layout::FLAG_EXPLICIT_TIMES, c("FLAG_EXPLICIT_TIMES"));
    assert_eq!(layout::FLAG_HAS_LAST, c("FLAG_HAS_LAST"));
    assert_eq!(layout::FLAG_UNIFORM_KNOTS, c("FLAG_UNIFORM_KNOTS"));
    assert_eq!(layout::MAX_BEZIER_DEGREE as u32, c("MAX_BEZIER_DEGREE"));
    assert_eq!(quatcurve::curve::MAX_ORDER as u32, c("MAX_ORDER"), "highest B-spline order");
    assert_eq!(quatcurve::curve::MAX_ORDER as u32 - 1, c("MAX_FACTORS"), "factors of an order-8 span");
    assert_eq!(2 * quatcurve::curve::MAX_ORDER as u32, c("KNOT_WINDOW"), "knots an order-8 span's basis reads");
    assert_eq!(layout::POLY_HERMITE, c("POLY_HERMITE"));
    // The table: the uniform B-spline bases of orders 2..=8, then Hermite's three functions.
    let bspline_functions: usize = (quatcurve::curve::MIN_ORDER..=quatcurve::curve::MAX_ORDER).map(|k| k - 1).sum();
    assert_eq!(layout::POLY_HERMITE as usize, bspline_functions);
    assert_eq!(layout::polynomial_table().len(), 2 * (bspline_functions + 3));
    assert_eq!(layout::polynomial_table().len(), c("POLY_ENTRIES") as usize, "the uniform table's declared length");
    // The kernel reads each track as whole vec4u words.
    assert_eq!(std::mem::size_of::<GpuTrack>(), 16 * c("TRACK_WORDS") as usize);
}

#[test]
fn fixed_point_times_round_trip() {
    for t in [0.0, 1.0 / 30.0, -2.75, 1036.6583333333333, -0.1, 1e6 + 0.123456789] {
        let [lo, hi] = layout::fixed_time(t);
        let back = (f64::from(hi as i32) * 4294967296.0 + f64::from(lo)) / 4294967296.0;
        assert!((back - t).abs() <= 2f64.powi(-33) * 1.0001, "{t}: {back}");
    }
    let [whole, hi, lo] = layout::fixed_step(1.0 / 30.0);
    let back = f64::from(whole) + f64::from(hi) * 2f64.powi(-32) + f64::from(lo) * 2f64.powi(-64);
    assert!((back - 1.0 / 30.0).abs() < 1e-18);
}

#[test]
fn the_forward_kinematics_program_validates_and_matches_its_host_struct() {
    for (name, text) in shader::FK_FILES {
        assert!(!text.trim().is_empty(), "{name} is empty");
    }
    let (module, _) = shader::fk_module().unwrap_or_else(|e| panic!("naga rejected the FK program:\n{e}"));
    assert!(shader::entry_workgroup_size(&module, shader::FK_ENTRY_POINT).unwrap() >= 32);
    let (_, ty) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("FkLevel")).expect("FkLevel in fk.wgsl");
    assert_eq!(ty.inner.size(module.to_ctx()) as usize, std::mem::size_of::<quatcurve::gpu::fk::FkLevel>());
    // The channel counts the kernel strides by are the texture's.
    assert_eq!(
        shader::constant_u32(&module, "FK_LOCAL_CHANNELS"),
        Some(quatcurve::bake::texture::LOCAL_CHANNELS as u32)
    );
    assert_eq!(
        shader::constant_u32(&module, "FK_MATRIX_CHANNELS"),
        Some(quatcurve::bake::texture::MATRIX_CHANNELS as u32)
    );
}

#[test]
fn the_playback_program_validates_and_matches_its_host_struct() {
    let (module, _) = shader::play_module().unwrap_or_else(|e| panic!("naga rejected the playback program:\n{e}"));
    for entry in [shader::PLAY_BLEND_ENTRY_POINT, shader::FK_ENTRY_POINT, shader::PLAY_PALETTE_ENTRY_POINT] {
        assert!(shader::entry_workgroup_size(&module, entry).unwrap() >= 32, "{entry}");
    }
    let (_, ty) =
        module.types.iter().find(|(_, t)| t.name.as_deref() == Some("PlayParams")).expect("PlayParams in play.wgsl");
    assert_eq!(ty.inner.size(module.to_ctx()) as usize, std::mem::size_of::<quatcurve::gpu::playback::PlayParams>());
    assert_eq!(shader::constant_u32(&module, "PLAY_POSE_CHANNELS"), Some(quatcurve::output::LOCAL_CHANNELS as u32));
    assert_eq!(shader::constant_u32(&module, "PLAY_MATRIX_CHANNELS"), Some(quatcurve::output::MATRIX_CHANNELS as u32));
}

#[test]
fn the_playback_from_curves_program_validates_and_matches_its_host_structs() {
    use quatcurve::gpu::playback::{PlayInstance, PlayTrack, PLAY_SOURCE_VALUE};
    let (module, _) =
        shader::play_curves_module().unwrap_or_else(|e| panic!("naga rejected the playback from curves:\n{e}"));
    for entry in [shader::PLAY_CURVES_ENTRY_POINT, shader::FK_ENTRY_POINT, shader::PLAY_PALETTE_ENTRY_POINT] {
        assert!(shader::entry_workgroup_size(&module, entry).unwrap() >= 32, "{entry}");
    }
    for (name, size) in
        [("PlayInstance", std::mem::size_of::<PlayInstance>()), ("PlayTrack", std::mem::size_of::<PlayTrack>())]
    {
        let (_, ty) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(name)).expect(name);
        assert_eq!(ty.inner.size(module.to_ctx()) as usize, size, "{name}");
    }
    assert_eq!(shader::constant_u32(&module, "PLAY_SOURCE_VALUE"), Some(PLAY_SOURCE_VALUE));
    assert_eq!(shader::constant_u32(&module, "PLAY_PROPERTIES"), Some(quatcurve::skeleton::POSE_PROPERTIES as u32));
}

#[test]
fn the_palette_vertex_shader_validates_and_reads_the_bone_shaders_vertex_inputs() {
    let (module, _) = shader::parse(&shader::PALETTE_VERTEX_FILES)
        .unwrap_or_else(|e| panic!("naga rejected the palette vertex shader:\n{e}"));
    let inputs = shader::vertex_inputs(&module, shader::PALETTE_VERTEX_ENTRY_POINT).unwrap();
    let (bones, _) = shader::parse(&shader::SKIN_VERTEX_FILES).unwrap();
    let bone_inputs = shader::vertex_inputs(&bones, shader::SKIN_VERTEX_ENTRY_POINT).unwrap();
    for input in &inputs {
        assert!(bone_inputs.contains(input), "{input:?} is not an input of skin_vertex.wgsl");
    }
    assert!(inputs.iter().any(|(n, _)| n == "joints") && inputs.iter().any(|(n, _)| n == "weights"));
}

#[test]
fn the_mesh_skinning_program_validates_and_matches_its_host_struct() {
    let (module, _) = shader::skin_mesh_module().unwrap_or_else(|e| panic!("naga rejected the skinning program:\n{e}"));
    assert!(shader::entry_workgroup_size(&module, shader::SKIN_MESH_ENTRY_POINT).unwrap() >= 32);
    let (_, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("SkinMeshJob"))
        .expect("SkinMeshJob in skin_mesh.wgsl");
    assert_eq!(ty.inner.size(module.to_ctx()) as usize, std::mem::size_of::<quatcurve::gpu::skinning::SkinMeshJob>());
    assert_eq!(shader::constant_u32(&module, "SKIN_VERTEX_CHANNELS"), Some(quatcurve::output::VERTEX_CHANNELS as u32));
    assert_eq!(shader::constant_u32(&module, "SKIN_MATRIX_CHANNELS"), Some(quatcurve::output::MATRIX_CHANNELS as u32));
}

/// The value of the shader's `f32` constant `name`.
fn constant_f32(module: &naga::Module, name: &str) -> f32 {
    let (_, constant) =
        module.constants.iter().find(|(_, c)| c.name.as_deref() == Some(name)).unwrap_or_else(|| panic!("no {name}"));
    match module.global_expressions[constant.init] {
        naga::Expression::Literal(naga::Literal::F32(v)) => v,
        ref other => panic!("{name} is {other:?}"),
    }
}

#[test]
fn series_limit_is_the_rusts() {
    let (module, _) = shader::module().unwrap();
    assert_eq!(f64::from(constant_f32(&module, "SERIES_LIMIT")), quatcurve::real::SERIES_LIMIT);
}

#[test]
fn sin_cos_reduction_is_the_rusts() {
    let (module, _) = shader::module().unwrap();
    let shader = ["HALF_PI_1", "HALF_PI_2", "HALF_PI_3"].map(|name| constant_f32(&module, name));
    assert_eq!(shader, quatcurve::cpu::HALF_PI_PARTS, "pi/2 in three parts");
    assert_eq!(constant_f32(&module, "TWO_OVER_PI"), std::f32::consts::FRAC_2_PI);
    // The parts add up to pi/2 beyond f32 precision, and the first takes k exactly.
    let sum: f64 = shader.iter().map(|&p| f64::from(p)).sum();
    assert!((sum - std::f64::consts::FRAC_PI_2).abs() < 1e-14, "{sum}");
    assert!(shader[0].to_bits().trailing_zeros() >= 16, "k * HALF_PI_1 must be exact for |k| < 2^16");
}

#[test]
fn bind_group_layouts_come_from_the_shaders() {
    use wgpu::{BindingType, BufferBindingType};
    let kind = |e: &wgpu::BindGroupLayoutEntry| match e.ty {
        BindingType::Buffer { ty: BufferBindingType::Uniform, .. } => "uniform",
        BindingType::Buffer { ty: BufferBindingType::Storage { read_only: true }, .. } => "read",
        BindingType::Buffer { ty: BufferBindingType::Storage { read_only: false }, .. } => "read_write",
        _ => "other",
    };
    let (eval, _) = shader::module().unwrap();
    let (fk, _) = shader::fk_module().unwrap();
    for (module, expected) in [
        (
            &eval,
            &[
                ("params", "uniform"),
                ("tracks", "read"),
                ("points", "read"),
                ("coefs", "read"),
                ("knots", "read"),
                ("times", "read"),
                ("out", "read_write"),
                ("poly", "uniform"),
            ][..],
        ),
        (
            &fk,
            &[
                ("fk_local", "read"),
                ("fk_parents", "read"),
                ("fk_level_joints", "read"),
                ("fk_model", "read_write"),
                ("fk_level", "uniform"),
            ][..],
        ),
    ] {
        let resources = quatcurve::gpu::program::Resources::of(module).unwrap();
        let got: Vec<(&str, &str)> = resources.iter().map(|(name, e)| (name, kind(e))).collect();
        assert_eq!(got, expected);
        // Binding numbers in order, as the layout lists them.
        let numbers: Vec<u32> = resources.layout_entries().iter().map(|e| e.binding).collect();
        assert!(numbers.windows(2).all(|w| w[0] < w[1]), "{numbers:?}");
        for (name, _) in expected {
            assert!(resources.binding(name).is_ok(), "{name}");
        }
    }
    assert!(quatcurve::gpu::program::Resources::of(&eval).unwrap().binding("nothing").is_err());
}

/// The shader's Taylor coefficients, typed as decimals in `shaders/real.wgsl`
/// (`horner_step(acc, x, c)`, highest power first), are the core's tables (`quatcurve::real`) rounded to f32.
#[test]
fn shader_series_are_these_series() {
    let wgsl =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/crates/shader/shaders/real.wgsl")).unwrap();
    let coefficients = |function: &str| -> Vec<f64> {
        let body = &wgsl[wgsl.find(&format!("fn {function}(")).unwrap_or_else(|| panic!("no fn {function}"))..];
        let body = &body[..body.find("\n}\n").expect("function end")];
        body.split("horner_step(acc, x, ")
            .skip(1)
            .map(|rest| rest[..rest.find(')').expect(")")].parse().expect("a number"))
            .collect()
    };
    for (function, series) in [
        ("cos_sqrt", &real::COS_SERIES[..]),
        ("sinc_sqrt", &real::SINC_SERIES[..]),
        ("atanc_sqrt", &real::ATANC_SERIES[..]),
    ] {
        let shader = coefficients(function);
        assert!(shader.len() >= 7, "{function}: {shader:?}");
        for (k, &c) in shader.iter().rev().enumerate() {
            assert_eq!(c as f32, series[k] as f32, "{function}: coefficient of x^{k}");
        }
    }
}
