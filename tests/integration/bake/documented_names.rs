//! The output names the docs give (`<stem>.<clip>.npy`, ...) held against what the bake writes
//! with the flags each is documented for: every such name in `docs/` and the README is in the
//! table below, at the line that documents it, and a bake with its flags writes a file of it.

use super::{bake, data_dir, stderr};
use std::path::Path;

/// (the documenting line, found by a marker in it; the name as written there; the input; the
/// bake's flags).
type Documented = (&'static str, &'static str, &'static str, &'static str, &'static [&'static str]);

const TABLE: &[Documented] = &[
    ("docs/BAKING.md", "the baked file is", "<stem>.glb", "CesiumMan.glb", &[]),
    ("docs/BAKING.md", "written back as", "<stem>.npz", "amass_sample.npz", &[]),
    ("docs/BAKING.md", "per clip an **animation texture**", "<name>.<clip>.npy", "CesiumMan.glb", &[]),
    ("docs/BAKING.md", "per glTF skin k", "<name>.<clip>.skin<k>.npy", "CesiumMan.glb", &["--texture", "skin"]),
    ("docs/BAKING.md", "| `local` |", "<name>.<clip>.npy", "CesiumMan.glb", &[]),
    ("docs/BAKING.md", "| `model` |", "<name>.<clip>.npy", "CesiumMan.glb", &["--texture", "model"]),
    ("docs/BAKING.md", "| `skin` |", "<name>.<clip>.skin<k>.npy", "CesiumMan.glb", &["--texture", "skin"]),
    ("docs/BAKING.md", "`--atlas` stacks", "<name>.npy", "CesiumMan.glb", &["--atlas"]),
    ("docs/BAKING.md", "and side views, to", "<name>.<clip>.preview.png", "CesiumMan.glb", &["--preview"]),
    ("docs/BAKING.md", "The sidecar", "<name>.json", "CesiumMan.glb", &[]),
    ("docs/DATASETS.md", "the baked file is", "<stem>.glb", "CesiumMan.fbx", &[]),
    ("docs/DESIGN.md", "- Textures (per clip", "<stem>.<clip>.npy", "CesiumMan.glb", &[]),
    ("docs/DESIGN.md", "- Textures (per clip", "<stem>.npy", "CesiumMan.glb", &["--atlas"]),
    ("docs/DESIGN.md", "per glTF skin k", "<stem>.<clip>.skin<k>.npy", "CesiumMan.glb", &["--texture", "skin"]),
    ("docs/DESIGN.md", "- Sidecar", "<stem>.json", "CesiumMan.glb", &[]),
    ("docs/DESIGN.md", "- `--preview`:", "<stem>.<clip>.preview.png", "CesiumMan.glb", &["--preview"]),
    ("docs/DESIGN.md", "named `<stem>", "<stem>.<clip>.<ext>", "CesiumMan.glb", &["--format", "exr"]),
    (
        "docs/DESIGN.md",
        "`<stem>.<clip>.mesh<k>.npy`",
        "<stem>.<clip>.mesh<k>.npy",
        "CesiumMan.glb",
        &["--texture", "vertex"],
    ),
    (
        "docs/DESIGN.md",
        "`<stem>.<clip>.mesh<k>.pos.<ext>`",
        "<stem>.<clip>.mesh<k>.pos.<ext>",
        "CesiumMan.glb",
        &["--texture", "vertex", "--format", "png16"],
    ),
    (
        "docs/DESIGN.md",
        "`<stem>.<clip>.mesh<k>.nrm.<ext>`",
        "<stem>.<clip>.mesh<k>.nrm.<ext>",
        "CesiumMan.glb",
        &["--texture", "vertex", "--format", "exr"],
    ),
    (
        "docs/DESIGN.md",
        "`--atlas`: `<stem>.mesh<k>",
        "<stem>.mesh<k>...",
        "CesiumMan.glb",
        &["--texture", "vertex", "--atlas"],
    ),
    ("docs/DESIGN.md", "**The mesh**", "<stem>.mesh.glb", "CesiumMan.glb", &["--texture", "vertex"]),
    (
        "docs/DESIGN.md",
        "**The file**, one per clip",
        "<stem>[.<clip>].skin<k>.json",
        "CesiumMan.glb",
        &["--texture", "skin", "--format", "babylon"],
    ),
    ("docs/DESIGN.md", "`<stem>.npz`.", "<stem>.npz", "amass_sample.npz", &[]),
    ("docs/DESIGN.md", "The baked file is `<stem>.glb`", "<stem>.glb", "CesiumMan.fbx", &[]),
    ("README.md", "beside `<stem>.mesh.glb`", "<stem>.mesh.glb", "CesiumMan.glb", &["--texture", "vertex"]),
    ("docs/BAKING.md", "`--usd` also writes", "<stem>.usda", "CesiumMan.glb", &["--usd"]),
    ("docs/DESIGN.md", "- **OpenUSD** (`--usd`)", "<stem>.usda", "CesiumMan.glb", &["--usd"]),
    ("docs/ENGINES.md", "`bake --usd` writes", "<stem>.usda", "Fox.glb", &["--usd"]),
    ("README.md", "`--usd` also writes", "<stem>.usda", "CesiumMan.glb", &["--usd"]),
];

/// Whether `file` is a name of `pattern` for an input of stem `stem`: `<stem>` and `<name>`
/// the stem, `<clip>` a clip's name (no dot), `<k>` a number, `<ext>` an image's extension,
/// `[...]` optional, `...` anything.
fn is_named(pattern: &str, stem: &str, file: &str) -> bool {
    if let Some(rest) = pattern.strip_prefix("...") {
        return (0..=file.len()).filter(|&i| file.is_char_boundary(i)).any(|i| is_named(rest, stem, &file[i..]));
    }
    if let Some(rest) = pattern.strip_prefix('[') {
        let (optional, after) = rest.split_once(']').expect("a [ closed by ]");
        return is_named(after, stem, file) || is_named(&format!("{optional}{after}"), stem, file);
    }
    for (token, matches) in [
        ("<stem>", &(|s: &str| s == stem) as &dyn Fn(&str) -> bool),
        ("<name>", &|s: &str| s == stem),
        ("<clip>", &|s: &str| !s.is_empty() && !s.contains('.')),
        ("<k>", &|s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit())),
        ("<ext>", &|s: &str| s == "exr" || s == "png"),
    ] {
        if let Some(rest) = pattern.strip_prefix(token) {
            return (1..=file.len())
                .filter(|&i| file.is_char_boundary(i))
                .any(|i| matches(&file[..i]) && is_named(rest, stem, &file[i..]));
        }
    }
    match pattern.chars().next() {
        None => file.is_empty(),
        Some(c) => file.starts_with(c) && is_named(&pattern[c.len_utf8()..], stem, &file[c.len_utf8()..]),
    }
}

#[test]
fn every_output_name_the_docs_give_is_one_the_bake_writes_with_the_flags_it_is_documented_for() {
    let Some(data) = data_dir() else { return };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    for (k, (doc, marker, name, input, flags)) in TABLE.iter().enumerate() {
        let text = std::fs::read_to_string(root.join(doc)).unwrap();
        let line = text.lines().find(|l| l.contains(marker)).unwrap_or_else(|| panic!("{doc}: no line has {marker:?}"));
        assert!(line.contains(&format!("`{name}`")), "{doc}: the line of {marker:?} does not give `{name}`: {line}");
        let out = dir.path().join(k.to_string());
        let baked = bake(
            &[&["--input", data.join(input).to_str().unwrap(), "--output", out.to_str().unwrap()], *flags].concat(),
        );
        assert!(baked.status.success(), "{input} {flags:?}: {}", stderr(&baked));
        let stem = input.split('.').next().unwrap();
        let written: Vec<String> =
            std::fs::read_dir(&out).unwrap().flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
        assert!(
            written.iter().any(|f| is_named(name, stem, f)),
            "{doc} says {input} baked with {flags:?} writes `{name}`; it wrote {written:?}"
        );
    }
}

#[test]
fn every_output_name_in_the_docs_is_in_the_table() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut docs: Vec<_> = std::fs::read_dir(root.join("docs"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.push(root.join("README.md"));
    let mut missing = Vec::new();
    for doc in docs {
        let relative = doc.strip_prefix(root).unwrap().to_string_lossy().into_owned();
        for (n, line) in std::fs::read_to_string(&doc).unwrap().lines().enumerate() {
            for name in
                line.split('`').skip(1).step_by(2).filter(|q| q.starts_with("<stem>") || q.starts_with("<name>"))
            {
                let listed = TABLE
                    .iter()
                    .any(|(d, marker, table_name, ..)| *d == relative && line.contains(marker) && *table_name == name);
                if !listed {
                    missing.push(format!("{relative}:{}: `{name}`", n + 1));
                }
            }
        }
    }
    assert!(missing.is_empty(), "output names the docs give that no test bakes:\n{}", missing.join("\n"));
}
