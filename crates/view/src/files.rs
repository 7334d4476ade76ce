//! Which file a request names: only a file under the served directory, reached without `..`
//! and without a symbolic link that leads out of it.

use std::path::{Path, PathBuf};

/// Why a request names no file the viewer serves.
#[derive(Debug, PartialEq, Eq)]
pub enum Refusal {
    /// A path outside the directory: `..`, an absolute path, a backslash, a NUL, or a link
    /// that leads out (HTTP 403).
    Outside(String),
    /// No such file under the directory (HTTP 404).
    Missing(String),
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::Outside(why) | Refusal::Missing(why) => f.write_str(why),
        }
    }
}

/// The file `relative` (a URL path after its route, still percent-encoded) names under `root`
/// (canonical). Every segment is decoded first, so `%2e%2e` is `..`; the canonical path must
/// still lie under `root`, so a link inside that points out is refused too.
///
/// # Errors
/// [`Refusal::Outside`] or [`Refusal::Missing`], naming the path.
pub fn resolve(root: &Path, relative: &str) -> Result<PathBuf, Refusal> {
    let decoded = percent_encoding::percent_decode_str(relative)
        .decode_utf8()
        .map_err(|_| Refusal::Outside(format!("'{relative}' is not UTF-8 once decoded")))?;
    let mut path = root.to_path_buf();
    for segment in decoded.split('/') {
        if segment.is_empty() || segment == "." {
            continue;
        }
        if segment == ".." || segment.contains(['\\', '\0', ':']) {
            return Err(Refusal::Outside(format!("'{decoded}' leaves the served directory")));
        }
        path.push(segment);
    }
    let canonical = path.canonicalize().map_err(|_| Refusal::Missing(format!("no file '{decoded}'")))?;
    if !canonical.starts_with(root) {
        return Err(Refusal::Outside(format!("'{decoded}' leads out of the served directory")));
    }
    if !canonical.is_file() {
        return Err(Refusal::Missing(format!("'{decoded}' is not a file")));
    }
    Ok(canonical)
}

/// `path` (under `root`) as the page names it: relative, `/`-separated, percent-encoded.
#[must_use]
pub fn url_path(root: &Path, path: &Path) -> String {
    const SEGMENT: &percent_encoding::AsciiSet =
        &percent_encoding::NON_ALPHANUMERIC.remove(b'-').remove(b'_').remove(b'.').remove(b'~');
    let relative = path.strip_prefix(root).unwrap_or(path);
    relative
        .components()
        .map(|c| percent_encoding::utf8_percent_encode(&c.as_os_str().to_string_lossy(), SEGMENT).to_string())
        .collect::<Vec<_>>()
        .join("/")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_files_under_the_root_are_served() {
        let outer = tempfile::tempdir().unwrap();
        let root = outer.path().join("served");
        std::fs::create_dir_all(root.join("sub dir")).unwrap();
        std::fs::write(root.join("sub dir/a.json"), "{}").unwrap();
        std::fs::write(outer.path().join("secret.txt"), "no").unwrap();
        let root = root.canonicalize().unwrap();
        let ok = resolve(&root, "sub%20dir/a.json").unwrap();
        assert_eq!(ok, root.join("sub dir/a.json"));
        assert_eq!(url_path(&root, &ok), "sub%20dir/a.json");
        for outside in ["../secret.txt", "%2e%2e/secret.txt", "sub%20dir/..%2f..%2fsecret.txt", "..%5csecret.txt"] {
            assert!(matches!(resolve(&root, outside), Err(Refusal::Outside(_))), "{outside}");
        }
        // An absolute path is read as relative to the root: not found there.
        assert!(matches!(resolve(&root, "/etc/passwd"), Err(Refusal::Missing(_))));
        assert!(matches!(resolve(&root, "sub%20dir"), Err(Refusal::Missing(_))));
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(outer.path().join("secret.txt"), root.join("link.txt")).unwrap();
            std::os::unix::fs::symlink(outer.path(), root.join("up")).unwrap();
            assert!(matches!(resolve(&root, "link.txt"), Err(Refusal::Outside(_))));
            assert!(matches!(resolve(&root, "up/secret.txt"), Err(Refusal::Outside(_))));
        }
    }
}
