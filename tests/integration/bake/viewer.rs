//! `quatcurve view`: its server refuses every path out of the served directory, and its page,
//! in Debian's headless Chromium (WebGL2 on SwiftShader, driven by `tests/browser/view.mjs`),
//! draws CesiumMan at a clip's first and last frames with the silhouette a CPU render of an
//! independent skinning of the same pose has, on both the bone-texture and the vertex-texture
//! paths; plays 1,000 of them; and through WebGPU plays Fox's clips from their curves,
//! blended, with the reference's silhouettes and the texture path's. `.ci/run` installs the browser and requires these tests
//! (`QUATCURVE_REQUIRE_BROWSER`).

use super::vertex::{independent, open};
use super::{bake, data_dir, json, stderr};
use glam::{DMat4, DVec3, DVec4};
use quatcurve::anim::curves::CurveChoice;
use quatcurve::anim::loops::LoopMode;
use quatcurve::formats::gltf::{self, UriPolicy};
use quatcurve::formats::mesh::skinned_primitives;
use quatcurve::output::VERTEX_CHANNELS;
use quatcurve::play::schedule::same_phase;
use quatcurve::play::{ClipTime, Instance, Playback};
use quatcurve::{skeleton, Device, DeviceChoice};
use std::io::{BufRead, Read, Write};
use std::path::{Path, PathBuf};

/// Silhouettes agree when the pixels inside one but not the other are at most this fraction
/// of the pixels inside either (rasterization rules differ on edge pixels, and the page's f32
/// skinning and texture reads differ from the f64 skinning by ~1e-6 of the box).
const SILHOUETTE_TOLERANCE: f64 = 0.01;

/// A channel this far (of 255) from the clear colour is the character.
const CLEAR_THRESHOLD: i32 = 12;

/// The drawing buffer of a captured frame, pixels a side.
const CAPTURE_SIZE: usize = 256;

/// The page's paths, as `bake_both` names its bakes and the page its renderers: a bone bake's
/// curves through WebGPU and its texture through WebGL2, a vertex bake's texture.
const PATHS: [(&str, &str); 3] = [("bones", "webgpu"), ("bones", "webgl2"), ("vertex", "webgl2")];

/// A running `quatcurve view`, stopped when dropped.
struct Server {
    child: std::process::Child,
    address: String,
}

impl Server {
    fn start(dir: &Path) -> Self {
        let mut child = std::process::Command::new(assert_cmd::cargo::cargo_bin("quatcurve"))
            .args(["view", dir.to_str().unwrap(), "--address", "127.0.0.1:0"])
            .stdout(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut first = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
        let address = first.trim().trim_start_matches("http://").trim_end_matches('/').to_string();
        assert!(address.starts_with("127.0.0.1:"), "the first line is the URL: {first:?}");
        Self { child, address }
    }

    /// `method target` as sent, byte for byte (no client normalizes `..` away): status, body.
    fn request(&self, method: &str, target: &str) -> (u16, Vec<u8>) {
        let mut stream = std::net::TcpStream::connect(&self.address).unwrap();
        write!(stream, "{method} {target} HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n\r\n", self.address).unwrap();
        let mut response = Vec::new();
        stream.read_to_end(&mut response).unwrap();
        let head_end = response.windows(4).position(|w| w == b"\r\n\r\n").expect("a whole response") + 4;
        let head = String::from_utf8_lossy(&response[..head_end]).into_owned();
        let status = head.split(' ').nth(1).and_then(|s| s.parse().ok()).expect("a status line");
        (status, response[head_end..].to_vec())
    }

    fn url(&self) -> String {
        format!("http://{}/", self.address)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn the_server_serves_files_under_its_directory_and_refuses_every_way_out() {
    let outer = tempfile::tempdir().unwrap();
    let dir = outer.path().join("served");
    std::fs::create_dir_all(dir.join("inner")).unwrap();
    std::fs::write(dir.join("inner/kept.json"), b"{\"kept\": 1}").unwrap();
    std::fs::write(outer.path().join("secret.txt"), b"not yours").unwrap();
    std::os::unix::fs::symlink(outer.path().join("secret.txt"), dir.join("link.txt")).unwrap();
    std::os::unix::fs::symlink(outer.path(), dir.join("up")).unwrap();
    let server = Server::start(&dir);
    assert_eq!(server.request("GET", "/files/inner/kept.json"), (200, b"{\"kept\": 1}".to_vec()));
    for way_out in [
        "/files/../secret.txt",
        "/files/inner/../../secret.txt",
        "/files/%2e%2e/secret.txt",
        "/files/%2E%2E%2Fsecret.txt",
        "/files/..%5csecret.txt",
        "/files/link.txt",
        "/files/up/secret.txt",
        "/texels/../secret.txt",
        "/api/scene?bake=..%2Fsecret.txt",
    ] {
        let (status, body) = server.request("GET", way_out);
        assert_eq!(status, 403, "{way_out}: {}", String::from_utf8_lossy(&body));
        assert!(!String::from_utf8_lossy(&body).contains("not yours"), "{way_out}");
    }
    assert_eq!(server.request("GET", "/files/%2Fetc%2Fpasswd").0, 404);
    assert_eq!(server.request("GET", "/files/inner").0, 404);
    assert_eq!(server.request("GET", "/nothing").0, 404);
    assert_eq!(server.request("POST", "/files/inner/kept.json").0, 405);
    // Not a sidecar, not an image: named, not a crash.
    let (status, body) = server.request("GET", "/texels/inner/kept.json");
    assert_eq!(status, 422, "{}", String::from_utf8_lossy(&body));
    assert!(String::from_utf8_lossy(&body).contains("inner/kept.json"));
    let (status, body) = server.request("GET", "/api/bakes");
    assert_eq!(status, 200);
    assert_eq!(
        serde_json::from_slice::<serde_json::Value>(&body).unwrap(),
        serde_json::json!({"bakes": [], "left_out": 0})
    );
    let (status, page) = server.request("GET", "/");
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&page).contains("viewer.js"));
}

#[test]
fn view_refuses_a_directory_it_cannot_serve_and_an_address_it_cannot_take() {
    let file = tempfile::NamedTempFile::new().unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (args, expected) in [
        (vec!["view", "/nonexistent/baked"], "/nonexistent/baked"),
        (vec!["view", file.path().to_str().unwrap()], "not a directory"),
        (vec!["view", dir.path().to_str().unwrap(), "--address", "not-an-address"], "--address not-an-address"),
    ] {
        let out = assert_cmd::Command::cargo_bin("quatcurve").unwrap().args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(stderr(&out).contains(expected), "{args:?}: {}", stderr(&out));
    }
}

/// `tests/browser/view.mjs` when Node, its `playwright-core` and Chromium are installed; else
/// skipped, unless `QUATCURVE_REQUIRE_BROWSER` is set.
pub(super) fn browser() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser");
    let chromium = std::env::var_os("QUATCURVE_CHROMIUM").map_or(PathBuf::from("/usr/bin/chromium"), PathBuf::from);
    let node = std::process::Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    let missing: Vec<String> = [
        (!node).then(|| "node".to_string()),
        (!dir.join("node_modules/playwright-core").exists())
            .then(|| "tests/browser/node_modules (npm ci --prefix tests/browser)".to_string()),
        (!chromium.exists()).then(|| format!("{} (apt-get install chromium)", chromium.display())),
    ]
    .into_iter()
    .flatten()
    .collect();
    if missing.is_empty() {
        return Some(dir.join("view.mjs"));
    }
    assert!(
        std::env::var_os("QUATCURVE_REQUIRE_BROWSER").is_none(),
        "QUATCURVE_REQUIRE_BROWSER is set and the browser test lacks {}",
        missing.join(", ")
    );
    eprintln!("skipped: the browser test lacks {}", missing.join(", "));
    None
}

/// Held while a page runs, here and in the engines' tests: one headless Chromium of the tests
/// at a time. Two at once, one of them drawing with WebGPU on SwiftShader, now and then lose the
/// WebGPU page's GPU process ("A valid external Instance reference no longer exists"): 1 run in
/// 2 of the viewer's tests here, and 1 CI run.
pub(super) static ONE_BROWSER: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Runs the page at `query` in headless Chromium (with WebGPU where the query asks for it) with
/// `args` for `view.mjs`; its result, with no page error and no request outside the viewer.
fn page(script: &Path, server: &Server, query: &str, args: &[&str]) -> serde_json::Value {
    let _one = ONE_BROWSER.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let out = tempfile::NamedTempFile::new().unwrap();
    let webgpu = query.contains("renderer=webgpu").then_some("--webgpu");
    let status = std::process::Command::new("node")
        .arg(script)
        .arg(format!("{}?{query}", server.url()))
        .arg(out.path())
        .args(args)
        .args(webgpu)
        .status()
        .unwrap();
    assert!(status.success(), "view.mjs failed on {query}");
    let result = json(out.path());
    assert_eq!(result["errors"], serde_json::json!([]), "page errors on {query}");
    assert_eq!(result["foreign"], serde_json::json!([]), "the page reached outside the viewer on {query}");
    result
}

/// The pixels of a captured frame that are not the clear colour, row 0 at the bottom.
fn page_mask(capture: &serde_json::Value) -> Vec<bool> {
    use base64::Engine;
    let rgba = base64::engine::general_purpose::STANDARD.decode(capture["rgba"].as_str().unwrap()).unwrap();
    let clear: Vec<i32> =
        capture["clear"].as_array().unwrap().iter().map(|c| (c.as_f64().unwrap() * 255.0).round() as i32).collect();
    rgba.chunks_exact(4).map(|p| (0..3).any(|c| (i32::from(p[c]) - clear[c]).abs() > CLEAR_THRESHOLD)).collect()
}

/// Pixel centres covered by the triangles of `positions` (`[vertices, VERTEX_CHANNELS]`)
/// moved by `offset` and projected by the page's `view_projection`, row 0 at the bottom as GL
/// counts window rows.
fn cpu_mask(positions: &[f64], indices: &[u32], offset: DVec3, view_projection: &DMat4, size: usize) -> Vec<bool> {
    let window: Vec<[f64; 2]> = positions
        .chunks_exact(VERTEX_CHANNELS)
        .map(|v| {
            let clip = *view_projection * (DVec3::new(v[0], v[1], v[2]) + offset).extend(1.0);
            assert!(clip.w > 0.0, "a vertex behind the camera");
            let ndc = DVec4::new(clip.x / clip.w, clip.y / clip.w, 0.0, 0.0);
            [(ndc.x + 1.0) / 2.0 * size as f64, (ndc.y + 1.0) / 2.0 * size as f64]
        })
        .collect();
    let mut mask = vec![false; size * size];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| window[t[k] as usize]);
        let edge = |p: [f64; 2], q: [f64; 2], x: f64, y: f64| (q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0]);
        let area = edge(a, b, c[0], c[1]);
        if area == 0.0 {
            continue;
        }
        let lo = |k: usize| a[k].min(b[k]).min(c[k]).floor().max(0.0) as usize;
        let hi = |k: usize| (a[k].max(b[k]).max(c[k]).ceil() as usize).min(size);
        for y in lo(1)..hi(1) {
            for x in lo(0)..hi(0) {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let w = [edge(b, c, px, py), edge(c, a, px, py), edge(a, b, px, py)];
                if w.iter().all(|&w| w * area >= 0.0) {
                    mask[y * size + x] = true;
                }
            }
        }
    }
    mask
}

/// A captured frame's mask, and its mismatch against each of `poses` (skinned positions)
/// drawn on the CPU with the frame's camera and first instance's offset.
fn against_poses(capture: &serde_json::Value, poses: &[Vec<f64>], indices: &[u32]) -> (Vec<bool>, Vec<f64>) {
    let numbers =
        |key: &str| -> Vec<f64> { capture[key].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect() };
    let view_projection = DMat4::from_cols_slice(&numbers("view_projection"));
    let offset = DVec3::from_slice(&numbers("offsets")[..3]);
    let mask = page_mask(capture);
    let against = poses
        .iter()
        .map(|pose| mismatch(&mask, &cpu_mask(pose, indices, offset, &view_projection, CAPTURE_SIZE)))
        .collect();
    (mask, against)
}

/// Pixels in one mask but not the other, as a fraction of the pixels in either.
fn mismatch(a: &[bool], b: &[bool]) -> f64 {
    let either = a.iter().zip(b).filter(|(a, b)| **a || **b).count();
    let one = a.iter().zip(b).filter(|(a, b)| a != b).count();
    one as f64 / either.max(1) as f64
}

/// `source` baked into `bones/` (`skin-trs`) and `vertex/` (`vertex`) of a new directory, in
/// `formats` (bones', vertices').
fn bake_both(source: &Path, formats: [&str; 2]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for ((sub, texture), format) in [("bones", "skin-trs"), ("vertex", "vertex")].into_iter().zip(formats) {
        let output = dir.path().join(sub);
        let args = ["--input", source.to_str().unwrap(), "--texture", texture, "--format", format];
        let out = bake(&[&args[..], &["--output", output.to_str().unwrap()]].concat());
        assert!(out.status.success(), "{}", stderr(&out));
    }
    dir
}

#[test]
fn the_page_draws_the_silhouette_of_an_independent_cpu_skinning_on_every_path() {
    let (Some(script), Some(data)) = (browser(), data_dir()) else { return };
    let source = data.join("CesiumMan.glb");
    // PNG16 for bones (its remap through the layout), EXR for vertices; the other way round below.
    let dir = bake_both(&source, ["png16", "exr"]);
    // Poses at keys spread over the walk (the clip's first key, at 0.0417 s, is its first
    // frame), skinned without quatcurve's bake; the page is asked for the same times, on the
    // source's clock as three.js's AnimationMixer counts it.
    let (document, buffers) = open(&source);
    let channel = document.animations().next().unwrap().channels().next().unwrap();
    let keys: Vec<f32> = channel.reader(|b| buffers.get(b.index()).map(Vec::as_slice)).read_inputs().unwrap().collect();
    let times: Vec<f64> = [0, keys.len() / 4, keys.len() / 2, keys.len() - 1].map(|k| f64::from(keys[k])).to_vec();
    let file = gltf::read(&source, UriPolicy::default()).unwrap();
    let primitive = &skinned_primitives(&file).unwrap().primitives[0];
    let indices = primitive.indices.clone().unwrap();
    let poses: Vec<Vec<f64>> = times.iter().map(|&t| independent(&source, primitive, 0, t)).collect();
    let server = Server::start(dir.path());
    for (bake, renderer) in PATHS {
        let path = format!("{bake} on {renderer}");
        for (k, time) in times.iter().enumerate() {
            // From the side, where a walk's stride shows in the silhouette.
            let query = format!(
                "bake={bake}%2FCesiumMan.json&renderer={renderer}&instances=1&paused=1&time={time}&azimuth=90&width={CAPTURE_SIZE}&height={CAPTURE_SIZE}&antialias=0",
            );
            let result = page(&script, &server, &query, &["--capture"]);
            assert_eq!(result["path"], renderer, "{query}: {}", result["message"]);
            let (page, against) = against_poses(&result["capture"], &poses, &indices);
            let inside = page.iter().filter(|&&p| p).count();
            let others =
                against.iter().enumerate().filter(|&(j, _)| j != k).map(|(_, &m)| m).fold(f64::INFINITY, f64::min);
            eprintln!(
                "{path} at {:.4} s: {inside} pixels drawn, silhouette mismatch {:.4} against the same pose, at least {others:.4} \
                 against the others ({})",
                times[k],
                against[k],
                result["renderer"]
            );
            assert!(inside > 500, "{path} at {time} s: the character takes {inside} pixels");
            assert!(
                against[k] <= SILHOUETTE_TOLERANCE,
                "{path} at {time} s: mismatch {} > {SILHOUETTE_TOLERANCE}",
                against[k]
            );
            // The comparison tells poses apart: every other pose is well outside the tolerance.
            assert!(others > 3.0 * SILHOUETTE_TOLERANCE, "{path} at {time} s: another pose differs by only {others}");
        }
    }
}

/// RobotExpressive hangs 12 of its 14 meshes from bones without a skin: every path draws the
/// whole robot (rigid parts bound to their bones) with the silhouette of an independent
/// placement of every primitive (rigid parts by their node's world transform).
#[test]
fn the_page_draws_rigid_parts_where_their_nodes_put_them_on_every_path() {
    let (Some(script), Some(data)) = (browser(), data_dir()) else { return };
    let source = data.join("RobotExpressive.glb");
    let dir = bake_both(&source, ["exr", "exr"]);
    let file = gltf::read(&source, UriPolicy::default()).unwrap();
    let drawn = skinned_primitives(&file).unwrap();
    assert_eq!((drawn.primitives.len(), drawn.not_drawn.len()), (19, 0));
    // Every primitive as one mesh: positions and indices offset by the vertices before them.
    let mut indices = Vec::new();
    let mut before = 0;
    for p in &drawn.primitives {
        let own = p.indices.clone().unwrap_or_else(|| (0..p.vertices() as u32).collect());
        indices.extend(own.iter().map(|i| i + before));
        before += p.vertices() as u32;
    }
    // Clip 0 (Dance) at two of its keys.
    let times = [0.5, 1.5];
    let poses: Vec<Vec<f64>> =
        times.iter().map(|&t| drawn.primitives.iter().flat_map(|p| independent(&source, p, 0, t)).collect()).collect();
    let server = Server::start(dir.path());
    for (bake, renderer) in PATHS {
        for (k, time) in times.iter().enumerate() {
            let query = format!(
                "bake={bake}%2FRobotExpressive.json&renderer={renderer}&instances=1&paused=1&time={time}&width={CAPTURE_SIZE}&height={CAPTURE_SIZE}&antialias=0"
            );
            let result = page(&script, &server, &query, &["--capture"]);
            assert_eq!(result["path"], renderer, "{query}: {}", result["message"]);
            let (page, against) = against_poses(&result["capture"], &poses, &indices);
            let inside = page.iter().filter(|&&p| p).count();
            eprintln!("RobotExpressive, {bake} on {renderer} at {time} s: {inside} pixels, mismatch {against:.4?}");
            assert!(against[k] <= SILHOUETTE_TOLERANCE, "{bake} on {renderer} at {time} s: mismatch {}", against[k]);
        }
    }
}

#[test]
fn the_page_plays_a_thousand_cesium_men_on_every_path() {
    let (Some(script), Some(data)) = (browser(), data_dir()) else { return };
    let dir = bake_both(&data.join("CesiumMan.glb"), ["exr", "png16"]);
    let server = Server::start(dir.path());
    for (bake, renderer) in PATHS {
        let path = format!("{bake} on {renderer}");
        let query = format!("bake={bake}%2FCesiumMan.json&renderer={renderer}&instances=1000");
        let result = page(&script, &server, &query, &["--measure", "2"]);
        assert_eq!(result["path"], renderer, "{query}: {}", result["message"]);
        let times: Vec<f64> = result["measure"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        eprintln!("{path}: 1000 CesiumMen, frames drawn and waited for in {times:?} ms ({})", result["renderer"]);
        assert_eq!(times.len(), 2);
        assert!(result["stats"].as_str().unwrap().contains("1000 instances"), "{}", result["stats"]);
    }
}

/// One page of the WebGPU test: its query, and the reference pose it must draw.
struct CurvePage {
    query: String,
    /// Index into the reference poses.
    pose: usize,
}

#[test]
fn the_webgpu_page_plays_the_curves_blended_as_the_texture_path_and_the_reference_draw_them() {
    let (Some(script), Some(data)) = (browser(), data_dir()) else { return };
    let source = data.join("Fox.glb");
    let dir = tempfile::tempdir().unwrap();
    let bones = dir.path().join("bones");
    let args = ["--input", source.to_str().unwrap(), "--texture", "skin-trs", "--format", "exr"];
    let out = bake(&[&args[..], &["--output", bones.to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    // Walk (clip 1) blended towards Run (clip 2) at the same phase of Run: play's rule, which the
    // page is held to here.
    let (walk, run) = (1, 2);
    let file = gltf::read(&source, UriPolicy::default()).unwrap();
    let primitive = &skinned_primitives(&file).unwrap().primitives[0];
    let indices = primitive.indices.clone().unwrap_or_else(|| (0..primitive.vertices() as u32).collect());
    let curve = CurveChoice::from_name(json(&bones.join("Fox.json"))["curve"].as_str().unwrap()).unwrap();
    let playback = Playback::new(file.animation.clone(), &curve, LoopMode::Auto, Some(0)).unwrap();
    let reference = Device::open(DeviceChoice::Reference).unwrap();
    let phase = |t: f64| same_phase(t, playback.duration(walk), playback.duration(run));
    // The reference's poses (time into Walk, weight), skinned on the CPU.
    let poses = [(0.2, 0.0), (0.2, 0.5), (0.2, 1.0), (0.45, 0.5)];
    let skinned: Vec<Vec<f64>> = poses
        .iter()
        .map(|&(t, w)| {
            let instance = Instance {
                first: ClipTime { clip: walk, time: t },
                second: Some((ClipTime { clip: run, time: phase(t) }, w)),
            };
            let palettes = playback.palettes(&reference, &[instance]).unwrap();
            skeleton::skin(&primitive.bind, playback.palette_joints(), &palettes)
        })
        .collect();
    let common = format!("bake=bones%2FFox.json&clip={walk}&blend={run}&instances=1&paused=1&azimuth=90&width={CAPTURE_SIZE}&height={CAPTURE_SIZE}&antialias=0");
    let mut pages: Vec<CurvePage> = poses
        .iter()
        .enumerate()
        .map(|(pose, &(t, w))| CurvePage { query: format!("{common}&renderer=webgpu&time={t}&weight={w}"), pose })
        .collect();
    // The bake's texture of Walk, drawn by WebGL2 with the same camera (the scene of Walk).
    pages.push(CurvePage { query: format!("{common}&renderer=webgl2&time={}", poses[0].0), pose: 0 });
    let server = Server::start(dir.path());
    // Counts the page cannot play are refused by name.
    for (query, status, says) in [("instances=0", 422, "0 instances"), ("instances=x", 400, "not a count")] {
        let (got, body) = server.request("GET", &format!("/api/curves?bake=bones%2FFox.json&{query}"));
        let body = String::from_utf8_lossy(&body);
        assert_eq!(got, status, "{query}: {body}");
        assert!(body.contains(says), "{query}: {body}");
    }
    let mut masks = Vec::new();
    for p in &pages {
        let result = page(&script, &server, &p.query, &["--capture"]);
        let expected = if p.query.contains("webgpu") { "webgpu" } else { "webgl2" };
        assert_eq!(result["path"], expected, "{}: {}", p.query, result["message"]);
        let (mask, against) = against_poses(&result["capture"], &skinned, &indices);
        let inside = mask.iter().filter(|&&m| m).count();
        eprintln!(
            "{}: {inside} pixels, mismatch against the reference poses {poses:?}: {against:.4?} ({})",
            p.query, result["renderer"]
        );
        assert!(inside > 500, "{}: the character takes {inside} pixels", p.query);
        assert!(
            against[p.pose] <= SILHOUETTE_TOLERANCE,
            "{}: mismatch {} > {SILHOUETTE_TOLERANCE}",
            p.query,
            against[p.pose]
        );
        // Every other time and weight draws another silhouette: a page that ignored the time or
        // the weight would match one of them instead.
        for (other, &m) in against.iter().enumerate().filter(|&(k, _)| k != p.pose) {
            assert!(m > 3.0 * SILHOUETTE_TOLERANCE, "{}: pose {:?} differs by only {m}", p.query, poses[other]);
        }
        masks.push(mask);
    }
    // WebGPU from the curves and WebGL2 from the texture draw Walk alike.
    let between = mismatch(&masks[0], &masks[pages.len() - 1]);
    eprintln!("Walk at {} s: WebGPU against WebGL2 {between:.4}", poses[0].0);
    assert!(between <= SILHOUETTE_TOLERANCE, "WebGPU and WebGL2 differ by {between}");
}

#[test]
fn a_bake_for_each_player_is_one_that_player_plays_and_the_view_page_lists_its_own_as_playable() {
    use quatcurve::bake::player::Player;
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fox = data.join("Fox.glb");
    for player in [Player::Three, Player::Babylon, Player::View] {
        let out = dir.path().join(player.name());
        let baked =
            bake(&["--input", fox.to_str().unwrap(), "--player", player.name(), "--output", out.to_str().unwrap()]);
        assert!(baked.status.success(), "{player}: {}", stderr(&baked));
        let sidecar = json(&out.join("Fox.json"));
        let (texture, format) = (sidecar["texture"].as_str().unwrap(), sidecar["format"].as_str().unwrap());
        assert!(player.refusals(texture.parse().unwrap(), format.parse().unwrap()).is_empty(), "{player}: {sidecar}");
        let options = &json(&out.join("manifest.0-of-1.json"))["options"];
        assert_eq!(
            (options["player"].as_str(), options["atlas"].as_bool()),
            (Some(player.name()), Some(player.plays().atlas))
        );
        let listed = quatcurve::view::scene::bakes(&out);
        let page = listed.bakes.iter().find(|b| b.sidecar == "Fox.json").unwrap();
        assert_eq!(
            page.playback.is_some(),
            player == Player::View || player == Player::Three,
            "{player}: {:?}",
            page.refusal
        );
    }
    // A texture the player cannot play is refused before anything is made, named with the player.
    let out = dir.path().join("refused");
    let refused = bake(&[
        "--input",
        fox.to_str().unwrap(),
        "--player",
        "view",
        "--texture",
        "model",
        "--output",
        out.to_str().unwrap(),
    ]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(
        stderr(&refused).contains("--player view: view plays skin-trs or vertex textures, not model"),
        "{}",
        stderr(&refused)
    );
    assert!(!out.exists());
}

#[test]
fn the_page_refuses_url_parameters_out_of_their_rules_and_says_which() {
    let (Some(script), Some(data)) = (browser(), data_dir()) else { return };
    let dir = tempfile::tempdir().unwrap();
    let baked = bake(&[
        "--input",
        data.join("Fox.glb").to_str().unwrap(),
        "--player",
        "view",
        "--output",
        dir.path().to_str().unwrap(),
    ]);
    assert!(baked.status.success(), "{}", stderr(&baked));
    let server = Server::start(dir.path());
    let size = "width=64&height=64&paused=1&renderer=webgl2";
    for (query, said) in [
        (
            "blend=9&weight=2&time=x&instances=0&clip=7",
            &[
                "instances=0 (a whole number, 1 or more)",
                "weight=2 (from 0 to 1)",
                "time=x (seconds)",
                "clip=7 (the bake has 3 clips: 0 to 2)",
                "blend=9 (the bake has 3 clips: 0 to 2)",
            ][..],
        ),
        ("blend=-1&weight=NaN", &["blend=-1 (a clip index)", "weight=NaN (from 0 to 1)"][..]),
    ] {
        // No page error (`page` holds that), every refusal named, and the defaults played.
        let result = page(&script, &server, &format!("{query}&{size}"), &["--capture"]);
        let message = result["message"].as_str().unwrap();
        for part in said {
            assert!(message.contains(part), "{query}: {message:?} lacks {part:?}");
        }
        let capture = &result["capture"];
        assert_eq!((capture["clip"].as_u64(), capture["blend"].as_u64()), (Some(0), Some(0)), "{query}: {capture}");
        assert_eq!(capture["weight"].as_f64(), Some(0.0), "{query}");
    }
    // Parameters within their rules are not refused.
    let result = page(&script, &server, &format!("blend=1&weight=0.5&clip=2&{size}"), &["--capture"]);
    assert!(!result["message"].as_str().unwrap().contains("refused"), "{}", result["message"]);
    assert_eq!(result["capture"]["blend"].as_u64(), Some(1));
}
