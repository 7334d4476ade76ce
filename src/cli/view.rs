//! `quatcurve view DIR`: serves a baked directory to the viewer page (DESIGN section 9).

use super::Failure;
use clap::Args;
use quatcurve::view::{self, scene, Viewer};
use std::io::Write;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// The baked directory (a `bake --output`): its `skin-trs` and `vertex` bakes of
    /// `--format exr|png16` play; files outside it are never served.
    dir: PathBuf,
    /// The address to listen on. The default answers this machine only; another address (say
    /// 0.0.0.0:8765) serves the directory to the network. Port 0 takes a free port.
    #[arg(long, default_value = view::DEFAULT_ADDRESS)]
    address: String,
}

pub fn run(args: &ViewArgs) -> Result<(), Failure> {
    let viewer = Viewer::new(&args.dir).map_err(|e| Failure::Input(format!("{}: {e}", args.dir.display())))?;
    let (server, address) = view::bind(&args.address).map_err(|e| Failure::Input(format!("--address {e}")))?;
    let listing = scene::bakes(viewer.root());
    let bakes = &listing.bakes;
    let playable = bakes.iter().filter(|b| b.playback.is_some()).count();
    // The first line is the URL (scripts read it to find a free port's number).
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "http://{address}/");
    let _ =
        writeln!(out, "serving {} ({} bakes, {playable} playable); Ctrl-C stops", viewer.root().display(), bakes.len());
    for bake in bakes.iter().filter(|b| b.playback.is_none()) {
        let _ = writeln!(out, "  {} does not play: {}", bake.sidecar, bake.refusal.as_deref().unwrap_or(""));
    }
    if listing.left_out > 0 {
        let _ = writeln!(
            out,
            "  the page lists the first {} bakes; {} more JSON files were not read",
            scene::MAX_LISTED,
            listing.left_out
        );
    }
    let _ = out.flush();
    drop(out);
    viewer.serve(&server);
    Ok(())
}
