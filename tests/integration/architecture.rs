//! `ARCHITECTURE.md`'s map held against the code, read from the document itself so the two
//! cannot drift apart:
//! - a crate depends only on crates listed above it and named on its section's `May import`
//!   line (every workspace member has a section);
//! - no module imports from a layer above its own, in any crate;
//! - inside each directory no file names a sibling listed after it (`mod.rs` last unless listed);
//! - no circle of imports between files (re-exports, `pub use`, are a module's face, not a use);
//! - modules import an item from the module that defines it, not through a crate root;
//! - the library's code (messages included) spells no command-line flag: it names options by
//!   their library names, and the command line shows them as its flags.
//!
//! Imports are read from code with comments and strings blanked: `use` trees, grouped ones
//! (`use super::{a, b::C}`) expanded, and paths written inline (`crate::x::f()`), each resolved
//! to the file that defines it, inline modules (`mod tests { use super::*; }`) included.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
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

/// `text` with comments, string and character literals blanked (newlines kept, so line
/// numbers hold): what is left is code.
fn code_of(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            loop {
                if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
        } else if c == 'r' && (next == Some('"') || next == Some('#')) && !prev_is_ident(&chars, i) {
            // A raw string: r"..." or r#"..."#.
            let hashes = chars[i + 1..].iter().take_while(|&&h| h == '#').count();
            if chars.get(i + 1 + hashes) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            let close: String = std::iter::once('"').chain(std::iter::repeat('#').take(hashes)).collect();
            let body_start = i + 2 + hashes;
            let rest: String = chars[body_start..].iter().collect();
            let end = body_start + rest.find(&close).map(|b| rest[..b].chars().count()).unwrap() + close.len();
            out.extend(chars[i..end].iter().map(|&c| blank(c)));
            i = end;
        } else if c == '"' {
            out.push(' ');
            i += 1;
            while chars[i] != '"' {
                let skip = if chars[i] == '\\' { 2 } else { 1 };
                out.extend(chars[i..i + skip].iter().map(|&c| blank(c)));
                i += skip;
            }
            out.push(' ');
            i += 1;
        } else if c == '\'' && char_literal_len(&chars[i..]).is_some() {
            let len = char_literal_len(&chars[i..]).unwrap();
            out.extend(std::iter::repeat(' ').take(len));
            i += len;
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

fn prev_is_ident(chars: &[char], i: usize) -> bool {
    i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_')
}

/// The length of a character literal starting at `s[0] == '\''`, or None for a lifetime.
fn char_literal_len(s: &[char]) -> Option<usize> {
    if s.get(1) == Some(&'\\') {
        let close = s[2..].iter().position(|&c| c == '\'')?;
        Some(close + 3)
    } else if s.get(2) == Some(&'\'') {
        Some(3)
    } else {
        None
    }
}

/// A workspace crate: its package name, the name code uses for it, and its source directory.
#[derive(Debug, Clone)]
struct Crate {
    package: String,
    ident: String,
    dir: PathBuf,
    /// The module its root is, when its name after `quatcurve-` is one of the layer table's
    /// modules (`quatcurve-gpu` is the module `gpu`: `src/lib.rs` is `gpu/mod.rs`, `src/fk.rs`
    /// `gpu/fk.rs`); empty for a crate whose root only declares modules.
    module: Vec<String>,
    /// A library (`src/lib.rs`), or a package's binary (`src/main.rs` and the modules it
    /// declares), which uses its library through the public API like any user.
    library: bool,
}

/// The `## Crates` section's crates, `### `package` (`path`)` each, in order.
fn crate_table(doc: &str) -> Vec<Crate> {
    let layers = layers(doc);
    let section = doc.split("## Crates").nth(1).expect("ARCHITECTURE.md has a `## Crates` section");
    let section = section.split("\n## ").next().unwrap();
    section
        .split("\n### ")
        .skip(1)
        .filter_map(|entry| {
            let heading = entry.lines().next()?;
            let (package, path) = match quoted(heading)[..] {
                [package, path, ..] => (package.to_string(), path),
                _ => return None,
            };
            let module = package.strip_prefix("quatcurve-").filter(|m| layers.contains_key(*m)).map(String::from);
            Some(Crate {
                ident: package.replace('-', "_"),
                module: module.into_iter().collect(),
                package,
                dir: root().join(path),
                library: true,
            })
        })
        .collect()
}

/// Each crate's `- May import:` line in the `## Crates` section: the workspace crates it names.
fn may_import(doc: &str) -> HashMap<String, Vec<String>> {
    let section = doc.split("## Crates").nth(1).unwrap().split("\n## ").next().unwrap();
    section
        .split("\n### ")
        .skip(1)
        .filter_map(|entry| {
            let package = quoted(entry.lines().next()?).first()?.to_string();
            let line = entry.lines().find(|l| l.starts_with("- May import:"))?;
            Some((package, quoted(line).into_iter().map(String::from).collect()))
        })
        .collect()
}

/// The workspace crates named in `dependencies`-like tables of a `Cargo.toml`.
fn workspace_dependencies(manifest: &str, crates: &[Crate]) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_dependencies = false;
    for line in manifest.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            in_dependencies = line.contains("dependencies");
            continue;
        }
        let Some((key, _)) = line.split_once('=') else { continue };
        let key = key.trim();
        if in_dependencies && crates.iter().any(|c| c.package == key) {
            out.push(key.to_string());
        }
    }
    out
}

/// One source file: its crate, its module path inside the crate, and its code.
struct File {
    krate: usize,
    path: PathBuf,
    module: Vec<String>,
    code: String,
}

impl File {
    fn label(&self) -> String {
        self.path.strip_prefix(root()).unwrap().display().to_string()
    }
}

/// The module path of a file under a crate's `src/`: `bake/mod.rs` -> `[bake]`, `lib.rs` -> `[]`.
fn module_of(relative: &Path) -> Vec<String> {
    let mut parts: Vec<String> = relative.iter().map(|p| p.to_str().unwrap().to_string()).collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

/// Every path a `use` tree names: `a::{b, c::{d as e, self}}` gives `a::b`, `a::c::d`, `a::c`.
fn expand(tree: &str) -> Vec<Vec<String>> {
    let tree: String = tree.split_whitespace().collect::<Vec<_>>().join(" ");
    let tree = tree.trim().trim_start_matches("::");
    if let Some(open) = tree.find('{') {
        let prefix: Vec<String> =
            tree[..open].trim_end_matches("::").split("::").filter(|s| !s.is_empty()).map(String::from).collect();
        let inner = &tree[open + 1..tree.rfind('}').unwrap()];
        let mut items = Vec::new();
        let (mut depth, mut start) = (0, 0);
        for (i, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    items.push(&inner[start..i]);
                    start = i + 1;
                }
                _ => {}
            }
        }
        items.push(&inner[start..]);
        let mut out = Vec::new();
        for item in items.into_iter().filter(|i| !i.trim().is_empty()) {
            for tail in expand(item) {
                let mut path = prefix.clone();
                path.extend(tail.into_iter().filter(|s| s != "self"));
                out.push(path);
            }
        }
        out
    } else {
        let name = tree.split(" as ").next().unwrap().trim();
        vec![name.split("::").map(|s| s.trim().to_string()).filter(|s| !s.is_empty() && s != "*").collect()]
    }
}

/// A path named in a file: where, in which module (inline modules included), and whether it
/// is a re-export.
struct Named {
    line: usize,
    scope: Vec<String>,
    path: Vec<String>,
    reexport: bool,
}

impl Named {
    /// Whether it is named in a file's unit tests (`mod tests`), which may reach any module
    /// of its crate without making the code circular.
    fn in_tests(&self, file: &File) -> bool {
        self.scope.get(file.module.len()).is_some_and(|m| m == "tests")
    }
}

/// Identifier-like tokens of `code` with their byte offsets (`::` kept as its own token).
fn tokens(code: &str) -> Vec<(usize, &str)> {
    let bytes = code.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i] as char;
        if c.is_alphanumeric() || c == '_' {
            let start = i;
            while i < bytes.len() && ((bytes[i] as char).is_alphanumeric() || bytes[i] == b'_') {
                i += 1;
            }
            out.push((start, &code[start..i]));
        } else if c == ':' && bytes.get(i + 1) == Some(&b':') {
            out.push((i, "::"));
            i += 2;
        } else {
            if !c.is_whitespace() {
                out.push((i, &code[i..i + 1]));
            }
            i += 1;
        }
    }
    out
}

/// Every path `file` names in `use` items and inline, with the module scope it is named in.
fn named_paths(file: &File) -> Vec<Named> {
    let code = &file.code;
    let line_of = |offset: usize| code[..offset].matches('\n').count() + 1;
    let tokens = tokens(code);
    let mut out = Vec::new();
    // Inline modules: (name, brace depth inside it).
    let mut scopes: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut t = 0;
    let scope_of = |scopes: &[(String, usize)]| {
        let mut s = file.module.clone();
        s.extend(scopes.iter().map(|(n, _)| n.clone()));
        s
    };
    while t < tokens.len() {
        let (offset, tok) = tokens[t];
        match tok {
            "{" => depth += 1,
            "}" => {
                if scopes.last().is_some_and(|&(_, d)| d == depth) {
                    scopes.pop();
                }
                depth -= 1;
            }
            "mod" if tokens.get(t + 2).is_some_and(|&(_, b)| b == "{") => {
                scopes.push((tokens[t + 1].1.to_string(), depth + 1));
                t += 1;
            }
            "use" => {
                let end = code[offset..].find(';').map(|e| offset + e).unwrap();
                let reexport = t > 0 && matches!(tokens[t - 1].1, "pub" | ")");
                for path in expand(&code[offset + 3..end]) {
                    out.push(Named { line: line_of(offset), scope: scope_of(&scopes), path, reexport });
                }
                while t < tokens.len() && tokens[t].0 < end {
                    t += 1;
                }
                continue;
            }
            "crate" | "super" | "self" if tokens.get(t + 1).is_some_and(|&(_, n)| n == "::") => {
                let before = if t > 0 { tokens[t - 1].1 } else { "" };
                if before != "::" && before != "in" {
                    let mut path = vec![tok.to_string()];
                    let mut k = t + 1;
                    while tokens.get(k).is_some_and(|&(_, n)| n == "::")
                        && tokens.get(k + 1).is_some_and(|&(_, n)| n.chars().all(|c| c.is_alphanumeric() || c == '_'))
                    {
                        path.push(tokens[k + 1].1.to_string());
                        k += 2;
                    }
                    out.push(Named { line: line_of(offset), scope: scope_of(&scopes), path, reexport: false });
                    t = k;
                    continue;
                }
            }
            _ => {}
        }
        t += 1;
    }
    out
}

/// Every source file of every crate in the table, and each crate's modules by path.
struct Workspace {
    crates: Vec<Crate>,
    files: Vec<File>,
    /// (crate, module path) -> file index, for file modules.
    modules: HashMap<(usize, Vec<String>), usize>,
    /// (crate, inline module path) -> file index of the file that holds it.
    inline: HashMap<(usize, Vec<String>), usize>,
}

impl Workspace {
    fn load() -> Self {
        let doc = read(&root().join("ARCHITECTURE.md"));
        let mut crates = crate_table(&doc);
        let mut files = Vec::new();
        for k in 0..crates.len() {
            let src = crates[k].dir.join("src");
            // The binary's modules: those `src/main.rs` declares.
            let main = src.join("main.rs");
            let bin_modules: Vec<String> = if main.is_file() {
                let code = code_of(&read(&main));
                let tokens = tokens(&code);
                tokens.windows(3).filter(|w| w[0].1 == "mod" && w[2].1 == ";").map(|w| w[1].1.to_string()).collect()
            } else {
                Vec::new()
            };
            let bin = main.is_file().then(|| {
                crates.push(Crate { ident: String::new(), library: false, module: Vec::new(), ..crates[k].clone() });
                crates.len() - 1
            });
            for path in sources(&src) {
                let own = module_of(path.strip_prefix(&src).unwrap());
                let in_bin = path == main || own.first().is_some_and(|m| bin_modules.contains(m));
                let krate = if in_bin { bin.unwrap() } else { k };
                let module = [crates[krate].module.clone(), own].concat();
                files.push(File { krate, code: code_of(&read(&path)), path, module });
            }
        }
        let modules = files.iter().enumerate().map(|(i, f)| ((f.krate, f.module.clone()), i)).collect();
        let mut workspace = Self { crates, files, modules, inline: HashMap::new() };
        for i in 0..workspace.files.len() {
            for named in named_paths(&workspace.files[i]) {
                if named.scope.len() > workspace.files[i].module.len() {
                    workspace.inline.insert((workspace.files[i].krate, named.scope.clone()), i);
                }
            }
        }
        workspace
    }

    /// The file defining the longest prefix of `path` (a module path in `krate`).
    fn file_of(&self, krate: usize, path: &[String]) -> Option<usize> {
        (0..=path.len()).rev().find_map(|n| {
            let key = (krate, path[..n].to_vec());
            self.modules.get(&key).or_else(|| self.inline.get(&key)).copied()
        })
    }

    /// Where a path named in `file` points: (crate, module path inside it), or None for a
    /// path outside the workspace (std, other crates, local items).
    fn resolve(&self, file: &File, named: &Named) -> Option<(usize, Vec<String>)> {
        let path = &named.path;
        let first = path.first()?.as_str();
        match first {
            "crate" => Some((file.krate, [&self.crates[file.krate].module[..], &path[1..]].concat())),
            "super" | "self" => {
                let mut scope = named.scope.clone();
                let mut rest = &path[..];
                while rest.first().is_some_and(|p| p == "super" || p == "self") {
                    if rest[0] == "super" {
                        scope.pop();
                    }
                    rest = &rest[1..];
                }
                scope.extend(rest.iter().cloned());
                Some((file.krate, scope))
            }
            _ => {
                if let Some(k) = self.crates.iter().position(|c| c.ident == first) {
                    return Some((k, [&self.crates[k].module[..], &path[1..]].concat()));
                }
                // A child module of the scope named without `self::`.
                let mut child = named.scope.clone();
                child.push(first.to_string());
                let key = (file.krate, child.clone());
                if self.modules.contains_key(&key) || self.inline.contains_key(&key) {
                    child.extend(path[1..].iter().cloned());
                    return Some((file.krate, child));
                }
                None
            }
        }
    }
}

/// Layer of each module, from the table rows `| N. name | `a`, `b` | ... |`.
fn layers(doc: &str) -> HashMap<String, usize> {
    let section = doc.split("## Layers").nth(1).expect("ARCHITECTURE.md has a `## Layers` section");
    let mut map = HashMap::new();
    for line in section.lines() {
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

#[test]
fn a_crate_depends_only_on_crates_listed_above_it_and_named_in_its_section() {
    let doc = read(&root().join("ARCHITECTURE.md"));
    let crates = crate_table(&doc);
    let allowed = may_import(&doc);
    assert!(crates.len() >= 2, "the crate sections did not parse: {crates:?}");
    let members = read(&root().join("Cargo.toml"));
    let members = members.split("members").nth(1).unwrap().split(']').next().unwrap();
    let mut broken = Vec::new();
    for member in quoted(&members.replace('"', "`")) {
        let manifest = read(&root().join(member).join("Cargo.toml"));
        let package = manifest.split("name = \"").nth(1).unwrap().split('"').next().unwrap();
        let Some(rank) = crates.iter().position(|c| c.package == package) else {
            broken.push(format!("{member}: {package} has no section in ARCHITECTURE.md's crates"));
            continue;
        };
        let Some(named) = allowed.get(package) else {
            broken.push(format!("{member}: {package}'s section has no `- May import:` line"));
            continue;
        };
        for dependency in workspace_dependencies(&manifest, &crates) {
            let theirs = crates.iter().position(|c| c.package == dependency).unwrap();
            if theirs >= rank {
                broken.push(format!("{member}/Cargo.toml: {package} depends on {dependency}, listed at or after it"));
            }
            if !named.contains(&dependency) {
                broken.push(format!(
                    "{member}/Cargo.toml: {package} depends on {dependency}, which its section does not name"
                ));
            }
        }
    }
    assert!(broken.is_empty(), "crate dependencies against ARCHITECTURE.md:\n{}", broken.join("\n"));
}

#[test]
fn no_module_imports_from_a_higher_layer() {
    let doc = read(&root().join("ARCHITECTURE.md"));
    let layers = layers(&doc);
    assert!(
        layers.len() >= 20 && layers["quat"] == 0 && layers["bake"] > layers["cpu"],
        "the layer table did not parse: {layers:?}"
    );
    let workspace = Workspace::load();
    let mut broken = Vec::new();
    for file in &workspace.files {
        // A crate root declares and re-exports; its modules hold the code.
        let Some(top) = file.module.first() else { continue };
        let own =
            *layers.get(top).unwrap_or_else(|| panic!("{}: `{top}` is in no layer of ARCHITECTURE.md", file.label()));
        for named in named_paths(file) {
            let Some((_, used)) = workspace.resolve(file, &named) else { continue };
            let Some(used) = used.first() else { continue };
            if layers.get(used).is_some_and(|&l| l > own) {
                broken.push(format!(
                    "{}:{}: {top} (layer {own}) uses {used} (layer {})",
                    file.label(),
                    named.line,
                    layers[used]
                ));
            }
        }
    }
    assert!(broken.is_empty(), "imports against ARCHITECTURE.md's layers:\n{}", broken.join("\n"));
}

#[test]
fn inside_a_directory_no_file_uses_a_module_listed_after_it() {
    let doc = read(&root().join("ARCHITECTURE.md"));
    let workspace = Workspace::load();
    // Sentences `Inside `dir/`: `a` < `b` (...) and `c` < `mod`.`, by directory.
    let mut orders: BTreeMap<String, HashMap<String, usize>> = BTreeMap::new();
    for sentence in doc.split("Inside ").skip(1) {
        let Some((dir, order)) = sentence.split_once(':') else { continue };
        let Some(dir) = dir.strip_prefix('`').and_then(|d| d.strip_suffix("/`")) else { continue };
        let dir = dir.to_string();
        let order = order.split('.').next().unwrap_or("");
        let rank = order
            .split(" < ")
            .enumerate()
            .flat_map(|(i, group)| quoted(group).into_iter().map(move |n| (n.to_string(), i)))
            .collect();
        orders.insert(dir, rank);
    }
    let mut broken = Vec::new();
    let mut directories = BTreeSet::new();
    for file in &workspace.files {
        let name = file.path.file_stem().unwrap().to_str().unwrap().to_string();
        if file.module.is_empty() {
            continue; // a crate root
        }
        let directory = file.module[..file.module.len() - usize::from(name != "mod")].to_vec();
        if directory.is_empty() {
            continue; // files beside the crate root: the layer table orders them
        }
        let dir = directory.join("/");
        directories.insert(dir.clone());
        let Some(rank) = orders.get(&dir) else {
            broken.push(format!("{}: ARCHITECTURE.md has no order for {dir}/", file.label()));
            continue;
        };
        // A `mod.rs` the sentence leaves out comes last.
        let own = match rank.get(&name) {
            Some(&r) => r,
            None if name == "mod" => usize::MAX,
            None => {
                broken.push(format!("{}: {name} is not in ARCHITECTURE.md's order for {dir}/", file.label()));
                continue;
            }
        };
        for named in named_paths(file).into_iter().filter(|named| !named.reexport) {
            let Some((k, used)) = workspace.resolve(file, &named) else { continue };
            if k != file.krate || used.len() <= directory.len() || used[..directory.len()] != directory[..] {
                continue;
            }
            let sibling = &used[directory.len()];
            if rank.get(sibling).is_some_and(|&r| r > own) {
                broken.push(format!(
                    "{}:{}: uses {sibling}, listed after {name} in the order for {dir}/",
                    file.label(),
                    named.line
                ));
            }
        }
    }
    assert!(broken.is_empty(), "imports against ARCHITECTURE.md's orders:\n{}", broken.join("\n"));
    let unused: Vec<_> = orders.keys().filter(|d| !directories.contains(*d)).collect();
    assert!(unused.is_empty(), "orders in ARCHITECTURE.md for directories that do not exist: {unused:?}");
}

#[test]
fn no_circle_of_imports_between_files() {
    let workspace = Workspace::load();
    let n = workspace.files.len();
    let mut edges: Vec<BTreeMap<usize, usize>> = vec![BTreeMap::new(); n];
    for (i, file) in workspace.files.iter().enumerate() {
        for named in named_paths(file).into_iter().filter(|named| !named.reexport && !named.in_tests(file)) {
            let Some((k, path)) = workspace.resolve(file, &named) else { continue };
            if let Some(j) = workspace.file_of(k, &path).filter(|&j| j != i) {
                edges[i].entry(j).or_insert(named.line);
            }
        }
    }
    // A circle is a file that reaches itself: search from each file, shortest first.
    let mut circles = BTreeSet::new();
    for start in 0..n {
        let mut from = vec![usize::MAX; n];
        let mut queue = std::collections::VecDeque::from([start]);
        while let Some(at) = queue.pop_front() {
            for &next in edges[at].keys() {
                if next == start {
                    let mut circle = vec![at];
                    while *circle.last().unwrap() != start {
                        circle.push(from[*circle.last().unwrap()]);
                    }
                    circle.reverse();
                    let lowest = circle.iter().enumerate().min_by_key(|&(_, &f)| f).unwrap().0;
                    circle.rotate_left(lowest);
                    circles.insert(circle);
                    queue.clear();
                    break;
                }
                if from[next] == usize::MAX && next != start {
                    from[next] = at;
                    queue.push_back(next);
                }
            }
        }
    }
    let described: Vec<String> = circles
        .iter()
        .map(|circle| {
            let mut steps: Vec<String> = circle
                .iter()
                .zip(circle.iter().cycle().skip(1))
                .map(|(&a, &b)| format!("{}:{}", workspace.files[a].label(), edges[a][&b]))
                .collect();
            steps.push(workspace.files[circle[0]].label());
            steps.join(" -> ")
        })
        .collect();
    assert!(described.is_empty(), "circles of imports between files:\n{}", described.join("\n"));
}

#[test]
fn modules_import_from_the_module_that_defines_an_item_not_a_crate_root() {
    let workspace = Workspace::load();
    let mut through_root = Vec::new();
    for file in workspace.files.iter().filter(|f| !f.module.is_empty() && workspace.crates[f.krate].library) {
        for named in named_paths(file) {
            let Some((k, path)) = workspace.resolve(file, &named) else { continue };
            let Some(first) = path.first() else { continue };
            // `crate::Batch` (a re-export), not `crate::batch::Batch`; and in a crate above,
            // `quatcurve_core::quat::...`, not `crate::quat` re-exported by its root.
            if first.starts_with(|c: char| c.is_ascii_uppercase())
                || !workspace.modules.contains_key(&(k, vec![first.clone()])) && path.len() > 1
            {
                through_root.push(format!("{}:{}: {}", file.label(), named.line, named.path.join("::")));
            }
        }
    }
    assert!(through_root.is_empty(), "imports through a crate root's re-exports:\n{}", through_root.join("\n"));
}

/// Python users read the library's messages too, and never typed a flag: outside the command
/// line's own code (`src/main.rs`, `src/cli/`), no line of code or string literal holds
/// `--` followed by a letter (comments may: they document the command line).
#[test]
fn the_library_spells_no_command_line_flag() {
    let mut found = Vec::new();
    for dir in ["src", "crates", "python/src"] {
        for path in sources(&root().join(dir)) {
            let relative = path.strip_prefix(root()).unwrap();
            if relative.starts_with("src/cli") || relative == Path::new("src/main.rs") {
                continue;
            }
            for (n, line) in read(&path).lines().enumerate() {
                let code = line.split("//").next().unwrap_or_default();
                let spelled = code
                    .match_indices("--")
                    .any(|(i, _)| code[i + 2..].chars().next().is_some_and(|c| c.is_ascii_lowercase()));
                if spelled && !line.trim_start().starts_with("//") {
                    found.push(format!("{}:{}: {}", relative.display(), n + 1, line.trim()));
                }
            }
        }
    }
    assert!(found.is_empty(), "library code spelling command-line flags:\n{}", found.join("\n"));
}

/// A crate packages on its own only if everything it compiles lies inside its directory: no
/// `include_str!` or `include_bytes!` of a library crate reaches above it (`cargo package
/// --no-verify`, which CI runs, checks the manifests, not what the code includes).
#[test]
fn every_crate_includes_only_files_inside_its_own_directory() {
    let crates = crate_table(&read(&root().join("ARCHITECTURE.md")));
    let mut outside = Vec::new();
    for krate in crates.iter().filter(|c| c.dir != root()) {
        for path in sources(&krate.dir.join("src")) {
            let text = read(&path);
            for (n, line) in text.lines().enumerate() {
                for include in ["include_str!(\"", "include_bytes!(\""] {
                    for (i, _) in line.match_indices(include) {
                        let target = line[i + include.len()..].split('"').next().unwrap_or_default();
                        let resolved = normalized(&path.parent().unwrap().join(target));
                        if !resolved.starts_with(&krate.dir) {
                            outside.push(format!(
                                "{}:{}: {target}",
                                path.strip_prefix(root()).unwrap().display(),
                                n + 1
                            ));
                        }
                    }
                }
            }
        }
    }
    assert!(outside.is_empty(), "files included from outside their crate's directory:\n{}", outside.join("\n"));
}

/// `path` with `.` and `..` resolved lexically.
fn normalized(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for part in path.components() {
        match part {
            std::path::Component::ParentDir => {
                out.pop();
            }
            std::path::Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// Errors are enums with fields up to the top, never text: no library crate's function returns
/// `Result<_, String>`, and no error variant is a message alone (`#[error("{0}")] Name(String)`,
/// where a lower error's text or a sentence built at the call would go). The front ends (the
/// command line, the Python module) turn errors into their own: exit codes and messages,
/// exceptions.
#[test]
fn library_crates_return_typed_errors_not_strings() {
    let crates = crate_table(&read(&root().join("ARCHITECTURE.md")));
    let mut found = Vec::new();
    for krate in crates.iter().filter(|c| c.dir.starts_with(root().join("crates"))) {
        for path in sources(&krate.dir.join("src")) {
            let text = read(&path);
            let at = |n: usize, line: &str| {
                format!("{}:{}: {}", path.strip_prefix(root()).unwrap().display(), n + 1, line.trim())
            };
            for (n, line) in code_of(&text).lines().enumerate() {
                let squeezed: String = line.split_whitespace().collect();
                if squeezed.contains("Result<") && squeezed.contains(",String>") {
                    found.push(at(n, line));
                }
            }
            let lines: Vec<&str> = text.lines().map(str::trim).collect();
            for (n, line) in lines.iter().enumerate() {
                if *line == r#"#[error("{0}")]"# {
                    let variant = lines[n + 1..].iter().find(|l| !l.starts_with("///")).copied().unwrap_or_default();
                    if variant.ends_with("(String),") {
                        found.push(at(n, variant));
                    }
                }
            }
        }
    }
    assert!(found.is_empty(), "text where a typed error belongs:\n{}", found.join("\n"));
}
