//! The WGSL program: composed from `shaders/*.wgsl` (the only place the GPU math lives),
//! validated by naga, and the source of the layout facts the host needs (workgroup size).

/// The shader files in the order they are concatenated into one module. WGSL has no
/// `#include`; module-scope declarations are order-independent, so order is only for reading.
pub const FILES: [(&str, &str); 5] = [
    ("real.wgsl", include_str!("../../shaders/real.wgsl")),
    ("quat.wgsl", include_str!("../../shaders/quat.wgsl")),
    ("basis.wgsl", include_str!("../../shaders/basis.wgsl")),
    ("segment.wgsl", include_str!("../../shaders/segment.wgsl")),
    ("eval.wgsl", include_str!("../../shaders/eval.wgsl")),
];

/// Name of the compute entry point.
pub const ENTRY_POINT: &str = "evaluate";

/// Name of the write-only roofline entry point (same bindings and output bytes, no math).
pub const ROOFLINE_ENTRY_POINT: &str = "roofline";

/// The whole program as one WGSL source.
#[must_use]
pub fn source() -> String {
    FILES.iter().map(|(_, text)| *text).collect::<Vec<_>>().join("\n")
}

/// Parses and validates the program with naga.
///
/// # Errors
/// The parse or validation error, rendered with file context.
pub fn module() -> Result<(naga::Module, naga::valid::ModuleInfo), String> {
    let src = source();
    let module = naga::front::wgsl::parse_str(&src).map_err(|e| e.emit_to_string(&src))?;
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .map_err(|e| e.emit_to_string(&src))?;
    Ok((module, info))
}

/// The entry point's workgroup size (x), read from the parsed module so it is written once.
///
/// # Errors
/// When the entry point is missing or not one-dimensional.
pub fn workgroup_size(module: &naga::Module) -> Result<u32, String> {
    let ep = module.entry_points.iter().find(|e| e.name == ENTRY_POINT).ok_or("no `evaluate` entry point")?;
    match ep.workgroup_size {
        [x, 1, 1] if x > 0 => Ok(x),
        other => Err(format!("workgroup size {other:?} is not one-dimensional")),
    }
}

/// A `u32` module-scope constant, by name (curve codes, limits).
#[must_use]
pub fn constant_u32(module: &naga::Module, name: &str) -> Option<u32> {
    let (_, c) = module.constants.iter().find(|(_, c)| c.name.as_deref() == Some(name))?;
    match module.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => Some(v),
        _ => None,
    }
}
