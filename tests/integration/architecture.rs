//! `ARCHITECTURE.md`'s layer map held against the code: no module imports from a layer above
//! its own, and inside `cpu/`, `gpu/`, `batch/`, `interp/`, `bake/`, `view/` and `fit/` no file names a sibling module listed after
//! it. The map is read from the document itself, so the two cannot drift apart.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.rs` file under `dir`.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(sources(&path));
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
    out.sort();
    out
}

/// The names in backticks in `text`.
fn quoted(text: &str) -> Vec<&str> {
    text.split('`').skip(1).step_by(2).collect()
}

/// Layer of each top-level module, from the table rows `| N. name | `a`, `b` | ... |`.
fn layers(doc: &str) -> HashMap<String, usize> {
    let mut map = HashMap::new();
    for line in doc.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let Some(layer) = cells.get(1).and_then(|c| c.split('.').next()).and_then(|n| n.parse::<usize>().ok()) else {
            continue;
        };
        for name in quoted(cells[2]) {
            map.insert(name.trim_end_matches('/').to_string(), layer);
        }
    }
    map
}

/// The code of a line: nothing after `//` (comments and doc comments name modules freely).
fn code(line: &str) -> &str {
    line.split("//").next().unwrap_or("")
}

/// Module names that follow `prefix` in `line`'s code (`crate::batch::X` gives `batch`).
fn after<'a>(line: &'a str, prefix: &str) -> Vec<&'a str> {
    code(line)
        .split(prefix)
        .skip(1)
        .map(|rest| rest.split(|c: char| !(c.is_alphanumeric() || c == '_')).next().unwrap_or(""))
        .collect()
}

/// Every line of every library file under `src/` outside the crate root and the front end
/// (which may use everything): (the file relative to `src/`, its top-level module, line
/// number from 1, the line).
fn library_lines() -> Vec<(PathBuf, String, usize, String)> {
    let src = root().join("src");
    let mut lines = Vec::new();
    for file in sources(&src) {
        let relative = file.strip_prefix(&src).unwrap().to_path_buf();
        let top =
            relative.components().next().unwrap().as_os_str().to_str().unwrap().trim_end_matches(".rs").to_string();
        if matches!(top.as_str(), "lib" | "main" | "cli") {
            continue;
        }
        for (n, line) in std::fs::read_to_string(&file).unwrap().lines().enumerate() {
            lines.push((relative.clone(), top.clone(), n + 1, line.to_string()));
        }
    }
    lines
}

#[test]
fn no_module_imports_from_a_higher_layer() {
    let doc = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let layers = layers(&doc);
    assert!(
        layers.len() >= 20 && layers["quat"] == 0 && layers["bake"] > layers["cpu"],
        "the layer table did not parse: {layers:?}"
    );
    let mut broken = Vec::new();
    for (relative, top, n, line) in library_lines() {
        let own = *layers.get(&top).unwrap_or_else(|| panic!("src/{top} is in no layer of ARCHITECTURE.md"));
        for used in after(&line, "crate::") {
            if layers.get(used).is_some_and(|&l| l > own) {
                broken.push(format!(
                    "src/{}:{n}: {top} (layer {own}) uses {used} (layer {})",
                    relative.display(),
                    layers[used]
                ));
            }
        }
    }
    assert!(broken.is_empty(), "imports against ARCHITECTURE.md's layers:\n{}", broken.join("\n"));
}

#[test]
fn inside_a_directory_no_file_uses_a_module_listed_after_it() {
    let doc = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let mut checked = 0;
    // Sentences `Inside `dir/`: `a` < `b` (...) and `c` < `mod`.`
    for sentence in doc.split("Inside ").skip(1) {
        let Some((dir, order)) = sentence.split_once(':') else { continue };
        let dir = quoted(dir).first().map(|d| d.trim_end_matches('/')).unwrap_or("");
        let order = order.split('.').next().unwrap_or("");
        let path = root().join("src").join(dir);
        if dir.is_empty() || !path.is_dir() {
            continue;
        }
        let module = |name: &str| path.join(format!("{name}.rs")).is_file() || name == "mod";
        let rank: HashMap<&str, usize> = order
            .split(" < ")
            .enumerate()
            .flat_map(|(i, group)| quoted(group).into_iter().filter(|n| module(n)).map(move |n| (n, i)))
            .collect();
        for file in sources(&path) {
            let name = file.file_stem().unwrap().to_str().unwrap();
            // A `mod.rs` the sentence leaves out comes last.
            let own = match rank.get(name) {
                Some(&r) => r,
                None if name == "mod" => usize::MAX,
                None => panic!("src/{dir}/{name}.rs is not in ARCHITECTURE.md's order for {dir}/"),
            };
            for (n, line) in std::fs::read_to_string(&file).unwrap().lines().enumerate() {
                let named = after(line, "super::").into_iter().chain(after(line, &format!("crate::{dir}::")));
                for used in named {
                    if rank.get(used).is_some_and(|&r| r > own) {
                        panic!("src/{dir}/{name}.rs:{}: uses {used}, listed after it in ARCHITECTURE.md", n + 1);
                    }
                }
            }
        }
        checked += 1;
    }
    assert_eq!(checked, 7, "expected the orders of cpu/, gpu/, batch/, interp/, bake/, view/ and fit/");
}

#[test]
fn modules_import_from_the_module_that_defines_an_item_not_the_crate_root() {
    let mut through_root = Vec::new();
    for (relative, _, n, line) in library_lines() {
        // `crate::Batch` (a re-export), not `crate::batch::Batch`.
        let root_item = after(&line, "crate::").iter().any(|name| name.starts_with(|c: char| c.is_ascii_uppercase()));
        if root_item || code(&line).contains("crate::{") {
            through_root.push(format!("src/{}:{n}: {}", relative.display(), line.trim()));
        }
    }
    assert!(through_root.is_empty(), "imports through the crate root's re-exports:\n{}", through_root.join("\n"));
}
