//! What sharing knots would cost a fitted clip: a layout whose cubic rotation channels share
//! one knot vector per segment (so a decoder computes the basis once per segment and sample,
//! not per channel) needs in each segment at least as many knots as the channel that needs
//! the most there. Summed over segments, that bounds from below the control points every
//! shared channel would store, against the points each channel's own knots store; the clip's
//! ratio is then estimated with the rest of its bytes unchanged and the same bytes a point.
//!
//! Run: `cargo run --release --example shared_knots -- FITTED.qcf... [--frames N]` (segments
//! of N source frames, 16 by default, as ACL's).

use quatcurve::qcf::fitted::{Fitted, Form, ORDER};
use quatcurve::qcf::{channel_bytes, clip_bytes, Container};

/// ACL's bytes for a raw bone-pose: a rotation, a translation and a scale in f32 (the figure
/// `fit` reports its ratio against).
const RAW_BONE_POSE_BYTES: usize = 40;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut frames = 16usize;
    let mut paths = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        if arg == "--frames" {
            frames = args.next().ok_or("--frames takes a count")?.parse()?;
        } else {
            paths.push(arg);
        }
    }
    println!("| clip | cubic rotations | points, own knots | points, shared knots (at least) | ratio, own | ratio, shared (at most) |");
    println!("|---|---:|---:|---:|---:|---:|");
    for path in paths {
        let container = Container::read(std::path::Path::new(&path))?;
        for clip in &container.clips {
            // Each cubic rotation channel's interior knot times, control points and bytes.
            let cubics: Vec<(&[f64], usize, usize)> = clip
                .channels
                .iter()
                .filter_map(|channel| match &channel.curve {
                    Fitted::Rotation(spline, _) if spline.form == Form::Cubic => {
                        let knots = &spline.fit.knots;
                        Some((&knots[ORDER..knots.len() - ORDER], spline.fit.controls.len(), channel_bytes(channel)))
                    }
                    _ => None,
                })
                .collect();
            let [start, end] = clip.span;
            let segment = frames as f64 / clip.source_rate();
            let segments = ((end - start) / segment).ceil() as usize;
            let shared_knots: usize = (0..segments)
                .map(|s| {
                    let (from, to) = (start + s as f64 * segment, start + (s + 1) as f64 * segment);
                    let inside = |knots: &[f64]| knots.iter().filter(|&&t| t >= from && t < to).count();
                    cubics.iter().map(|c| inside(c.0)).max().unwrap_or(0)
                })
                .sum();
            let own: usize = cubics.iter().map(|c| c.1).sum();
            let shared = cubics.len() * (shared_knots + ORDER);
            let cubic_bytes: usize = cubics.iter().map(|c| c.2).sum();
            let bytes = clip_bytes(clip) as f64;
            let estimate = bytes - cubic_bytes as f64 + cubic_bytes as f64 * shared as f64 / own as f64;
            let keys = ((end - start) * clip.source_rate()).round() as usize + 1;
            let raw = (keys * container.joints.len() * RAW_BONE_POSE_BYTES) as f64;
            println!(
                "| {} | {} | {own} | {shared} ({:.2}x) | {:.1}:1 | {:.1}:1 |",
                clip.name,
                cubics.len(),
                shared as f64 / own as f64,
                raw / bytes,
                raw / estimate
            );
        }
    }
    Ok(())
}
