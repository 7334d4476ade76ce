//! `quatcurve view DIR` (DESIGN section 9): a baked directory served on this machine to a
//! page that plays it as a crowd: its curves on the GPU through WebGPU, or its textures
//! through WebGL2 with the shipped shaders. Routes: `/` the page (the crate's `page/`), `/api/bakes` the
//! playable bakes, `/api/scene?bake=..&clip=..` one clip ready to draw ([`scene`]),
//! `/api/curves?bake=..&instances=..` the clips as curves on the GPU ([`curves`]),
//! `/texels/<file>` an image's texels as `f32` ([`texels`]),
//! `/files/<file>` a file as it is; only files under DIR ([`files`]).

pub mod curves;
pub mod error;
pub mod files;
pub mod scene;
pub mod texels;

use error::ViewError;
use files::Refusal;
use std::path::{Path, PathBuf};

/// Where `quatcurve view` listens unless told: this machine only.
pub const DEFAULT_ADDRESS: &str = "127.0.0.1:8765";

/// The page and its script, embedded: the binary serves them with nothing else installed.
const PAGE: &str = include_str!("../page/index.html");
const SCRIPT: &str = include_str!("../page/viewer.js");
const WEBGPU_SCRIPT: &str = include_str!("../page/webgpu.js");

/// An HTTP response.
#[derive(Debug)]
pub struct Reply {
    /// HTTP status.
    pub status: u16,
    /// `Content-Type`.
    pub content_type: &'static str,
    /// Body.
    pub body: Vec<u8>,
}

impl Reply {
    fn ok(content_type: &'static str, body: Vec<u8>) -> Self {
        Self { status: 200, content_type, body }
    }

    fn error(status: u16, message: &str) -> Self {
        Self { status, content_type: "text/plain; charset=utf-8", body: format!("{message}\n").into_bytes() }
    }

    fn json<T: serde::Serialize>(value: &T) -> Self {
        match serde_json::to_vec(value) {
            Ok(body) => Self::ok("application/json", body),
            Err(e) => Self::error(500, &e.to_string()),
        }
    }
}

impl From<Refusal> for Reply {
    fn from(refusal: Refusal) -> Self {
        match &refusal {
            Refusal::Outside(why) => Reply::error(403, why),
            Refusal::Missing(why) => Reply::error(404, why),
        }
    }
}

/// A served directory.
pub struct Viewer {
    root: PathBuf,
}

impl Viewer {
    /// Serves `dir`.
    ///
    /// # Errors
    /// When `dir` is not a readable directory.
    pub fn new(dir: &Path) -> Result<Self, ViewError> {
        let root = dir.canonicalize()?;
        if !root.is_dir() {
            return Err(ViewError::Lacks { what: "not a directory" });
        }
        Ok(Self { root })
    }

    /// The directory, canonical.
    #[must_use]
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The reply to `method url` (`url` as the request line has it: path and query, encoded).
    #[must_use]
    pub fn respond(&self, method: &str, url: &str) -> Reply {
        if method != "GET" && method != "HEAD" {
            return Reply::error(405, "only GET and HEAD");
        }
        let (path, query) = url.split_once('?').unwrap_or((url, ""));
        match path {
            "/" | "/index.html" => Reply::ok("text/html; charset=utf-8", PAGE.into()),
            "/viewer.js" => Reply::ok("text/javascript; charset=utf-8", SCRIPT.into()),
            "/webgpu.js" => Reply::ok("text/javascript; charset=utf-8", WEBGPU_SCRIPT.into()),
            "/api/bakes" => Reply::json(&scene::bakes(&self.root)),
            "/api/scene" => self.scene(query),
            "/api/curves" => self.curves(query),
            _ => {
                if let Some(file) = path.strip_prefix("/texels/") {
                    match files::resolve(&self.root, file) {
                        Ok(path) => match texels::Texels::read(&path) {
                            Ok(t) => Reply::ok("application/octet-stream", t.to_bytes()),
                            Err(e) => Reply::error(422, &format!("{}: {e}", files::url_path(&self.root, &path))),
                        },
                        Err(refusal) => refusal.into(),
                    }
                } else if let Some(file) = path.strip_prefix("/files/") {
                    match files::resolve(&self.root, file).map(|p| (std::fs::read(&p), content_type(&p))) {
                        Ok((Ok(body), kind)) => Reply::ok(kind, body),
                        Ok((Err(e), _)) => Reply::error(500, &e.to_string()),
                        Err(refusal) => refusal.into(),
                    }
                } else {
                    Reply::error(404, &format!("no page {path}"))
                }
            }
        }
    }

    /// `/api/scene?bake=<sidecar>&clip=<index>`.
    fn scene(&self, query: &str) -> Reply {
        self.with_bake(query, "clip", 0, |sidecar, clip| {
            scene::scene(&self.root, sidecar, clip).map(|s| Reply::json(&s))
        })
    }

    /// `/api/curves?bake=<sidecar>&instances=<count>`.
    fn curves(&self, query: &str) -> Reply {
        self.with_bake(query, "instances", 1, |sidecar, n| curves::curve_scene(sidecar, n).map(|s| Reply::json(&s)))
    }

    /// `answer` for the sidecar named by `query`'s `bake` and its count parameter `name`
    /// (`default` when absent): 400 for a parameter missing or not a count, the refusal of a
    /// path outside the directory, 422 naming the sidecar for what `answer` refuses.
    fn with_bake(
        &self,
        query: &str,
        name: &str,
        default: usize,
        answer: impl FnOnce(&Path, usize) -> Result<Reply, ViewError>,
    ) -> Reply {
        let param = |name: &str| {
            query.split('&').filter_map(|kv| kv.split_once('=')).find(|(k, _)| *k == name).map(|(_, v)| {
                percent_encoding::percent_decode_str(&v.replace('+', " ")).decode_utf8_lossy().into_owned()
            })
        };
        let Some(bake) = param("bake") else { return Reply::error(400, "no `bake` parameter") };
        let count = match param(name).map_or(Ok(default), |c| c.parse::<usize>()) {
            Ok(c) => c,
            Err(_) => return Reply::error(400, &format!("`{name}` is not a count")),
        };
        match files::resolve(&self.root, &bake) {
            Ok(sidecar) => answer(&sidecar, count)
                .unwrap_or_else(|e| Reply::error(422, &format!("{}: {e}", files::url_path(&self.root, &sidecar)))),
            Err(refusal) => refusal.into(),
        }
    }

    /// Answers `server`'s requests until the process ends.
    pub fn serve(&self, server: &tiny_http::Server) {
        for request in server.incoming_requests() {
            let reply = self.respond(request.method().as_str(), request.url());
            let header = |name: &str, value: &str| {
                tiny_http::Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("ASCII header")
            };
            let response = tiny_http::Response::from_data(reply.body)
                .with_status_code(reply.status)
                .with_header(header("Content-Type", reply.content_type))
                .with_header(header("Cache-Control", "no-store"))
                .with_header(header("X-Content-Type-Options", "nosniff"));
            // A client that went away is its own business; the server goes on.
            let _ = request.respond(response);
        }
    }
}

/// Listens on `address` (`host:port`; port 0 takes a free one) and gives the address taken.
///
/// # Errors
/// The system's reason the address cannot be listened on.
pub fn bind(address: &str) -> Result<(tiny_http::Server, std::net::SocketAddr), ViewError> {
    let server =
        tiny_http::Server::http(address).map_err(|reason| ViewError::Bind { address: address.into(), reason })?;
    let bound = server.server_addr().to_ip().ok_or_else(|| ViewError::NotIp { address: address.into() })?;
    Ok((server, bound))
}

fn content_type(path: &Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()) {
        Some("json") => "application/json",
        Some("glb") => "model/gltf-binary",
        Some("png") => "image/png",
        Some("exr") => "image/x-exr",
        _ => "application/octet-stream",
    }
}
