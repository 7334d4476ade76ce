//! The per-shard record of a bake (DESIGN section 13): what was read (size, SHA-256), with
//! which options, what was written (size, SHA-256) and how each input ended. `--resume` reads
//! it back to skip inputs whose outputs are intact, so a retried array task redoes only what
//! is missing or changed. Times and hosts live here, never in the outputs, so the outputs do
//! not depend on how the job was split.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::Path;

/// `manifest.<I>-of-<N>.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Manifest {
    /// `quatcurve <version>`.
    pub tool: String,
    /// Which share of the job this was.
    pub shard: ShardRecord,
    /// The options that decide the outputs; a resumed run with other options redoes all.
    pub options: serde_json::Value,
    /// The machine's host name, where known.
    pub host: Option<String>,
    /// Seconds since the Unix epoch when the run started.
    pub started: u64,
    /// Seconds since the Unix epoch when this was written.
    pub updated: u64,
    /// This shard's inputs, in job order.
    pub inputs: Vec<InputRecord>,
}

/// Which share of the job ran ([`crate::Shard`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardRecord {
    /// This shard's index, from 0.
    pub index: usize,
    /// Shards in the job.
    pub count: usize,
    /// Where the numbers came from (`--shard`, a scheduler's variables).
    pub source: String,
}

/// One input and what became of it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct InputRecord {
    /// As given or found (the built-in crowd: `built-in crowd`).
    pub path: String,
    /// The input's size in bytes.
    pub size: u64,
    /// The input's SHA-256, lowercase hex.
    pub sha256: String,
    /// `ok`, `resumed` (outputs of an earlier run verified and kept) or `failed`.
    pub status: String,
    /// Why it failed.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub error: Option<String>,
    /// The report's warnings (probably broken source keys, unbaked clip ends).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub warnings: Vec<String>,
    /// Wall time of reading, baking and writing it.
    pub seconds: f64,
    /// The files it wrote (or kept, resumed).
    pub outputs: Vec<FileRecord>,
}

/// A file by name (inside the output directory), size and SHA-256.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileRecord {
    /// Its name in the output directory.
    pub file: String,
    /// Its size in bytes.
    pub size: u64,
    /// Its SHA-256, lowercase hex.
    pub sha256: String,
}

impl FileRecord {
    /// Size and SHA-256 of `path`, recorded under `file`.
    pub fn of(path: &Path, file: String) -> std::io::Result<Self> {
        let (size, sha256) = hash_file(path)?;
        Ok(Self { file, size, sha256 })
    }

    /// Whether `dir/file` still has this size and hash.
    pub fn intact(&self, dir: &Path) -> bool {
        let path = dir.join(&self.file);
        std::fs::metadata(&path).is_ok_and(|m| m.len() == self.size)
            && hash_file(&path).is_ok_and(|(_, h)| h == self.sha256)
    }
}

/// Size and lowercase hex SHA-256 of a file, streamed.
pub fn hash_file(path: &Path) -> std::io::Result<(u64, String)> {
    let mut file = std::fs::File::open(path)?;
    let mut hasher = Sha256::new();
    let mut buffer = vec![0u8; 1 << 16];
    let mut size = 0u64;
    loop {
        let n = file.read(&mut buffer)?;
        if n == 0 {
            break;
        }
        hasher.update(&buffer[..n]);
        size += n as u64;
    }
    Ok((size, hex(&hasher.finalize())))
}

/// Lowercase hex SHA-256 of bytes.
pub fn hash_bytes(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// Lowercase hex of a digest (a streamed file's, hashed as it was written).
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Seconds since the Unix epoch.
pub fn now() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs())
}

/// The host name from the kernel or the environment, if any.
pub fn host() -> Option<String> {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|h| h.trim().to_string())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .filter(|h| !h.is_empty())
}

impl Manifest {
    /// The earlier manifest at `path`, if it exists and parses (a damaged one is ignored:
    /// everything is redone, which is always safe).
    pub fn load(path: &Path) -> Option<Self> {
        serde_json::from_slice(&std::fs::read(path).ok()?).ok()
    }

    /// The record of an earlier run that lets `input` be skipped: same options, same input
    /// bytes, success, and every output still as written.
    pub fn resumable(
        &self,
        options: &serde_json::Value,
        path: &str,
        size: u64,
        sha256: &str,
        dir: &Path,
    ) -> Option<&InputRecord> {
        if &self.options != options {
            return None;
        }
        self.inputs.iter().find(|r| {
            r.path == path
                && r.size == size
                && r.sha256 == sha256
                && matches!(r.status.as_str(), "ok" | "resumed")
                && r.outputs.iter().all(|o| o.intact(dir))
        })
    }
}
