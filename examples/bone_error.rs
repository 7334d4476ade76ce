//! How far a renderer interpolating baked bone textures (`shaders/bone_texture.wgsl`'s
//! `bone_pose`: nlerp between frames) strays from the curve between frames, per real clip and
//! rate, and the rate `--max-error-deg 0.5` chooses with its bytes against 30 Hz and the source's
//! own rate: the README's table and chart (`docs/bone-texture-error.png`).
//!
//! Run: `cargo run --release --example bone_error -- ../shared/data [CHART.png]`.

use quatcurve::anim::curves::CurveChoice;
use quatcurve::anim::loops::LoopMode;
use quatcurve::anim::Animation;
use quatcurve::bake::budget::{self, ErrorBudget, Setting};
use quatcurve::bake::texture::{Precision, TextureKind};
use quatcurve::formats::{bvh, gltf};
use quatcurve::plot::{self, Line};
use quatcurve::{Device, DeviceChoice};
use std::path::Path;

const FILES: [&str; 5] = ["CesiumMan.glb", "Fox.glb", "BrainStem.glb", "cmu_131_01.bvh", "cmu_131_03.bvh"];
const RATES: [f64; 6] = [15.0, 24.0, 30.0, 60.0, 120.0, 240.0];

/// The clip's key rate: the reciprocal of its most common key interval.
fn source_rate(animation: &Animation, clip: usize) -> f64 {
    let mut steps: Vec<f64> = animation.clips[clip]
        .channels
        .iter()
        .filter_map(|c| c.keyed())
        .flat_map(|(times, _)| times.windows(2).map(|w| w[1] - w[0]))
        .filter(|s| *s > 1e-9)
        .collect();
    steps.sort_by(f64::total_cmp);
    1.0 / steps.get(steps.len() / 2).copied().unwrap_or(1.0)
}

fn main() {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "../shared/data".into());
    let chart = std::env::args().nth(2);
    let device = Device::open(DeviceChoice::Cpu).expect("the CPU path opens");
    let curve = CurveChoice::Source;
    let setting = Setting {
        curve: &curve,
        looping: LoopMode::Auto,
        kind: TextureKind::Local,
        precision: Precision::F32,
        device: &device,
        measuring: &|_, _| {},
    };
    let budget = ErrorBudget { degrees: Some(0.5), max_rate: 2000.0, ..ErrorBudget::none() };
    let mut lines = Vec::new();
    let header = RATES.map(|r| format!("{r} Hz")).join(" | ");
    println!("| clip | {header} | `--max-error-deg 0.5` | bytes against 30 Hz | against the source rate |");
    println!("|---|{}---|---|---|", "---|".repeat(RATES.len()));
    for file in FILES {
        let path = Path::new(&dir).join(file);
        let animation = if file.ends_with(".bvh") {
            bvh::read(&path).expect("a BVH file").animation(path.file_stem().unwrap().to_str().unwrap())
        } else {
            gltf::read(&path, gltf::UriPolicy::default()).expect("a glTF file").animation
        };
        let chosen = budget::choose_rates(&animation, &budget, &setting).expect("a rate within 2000 Hz");
        for (c, clip) in animation.clips.iter().enumerate() {
            let mut points = Vec::new();
            let mut cells = Vec::new();
            for rate in RATES {
                let m = budget::measure(&animation, c, rate, &setting, quatcurve::anim::GLTF_UNIT_CM)
                    .expect("the clip bakes");
                points.push((rate, m.rotation.value));
                cells.push(format!("{:.3}", m.rotation.value));
            }
            let name = format!("{} {}", file.split('.').next().unwrap(), clip.name);
            let m = &chosen[c];
            // Frames of the same span at another rate (the bytes scale with them).
            let span = (m.frames - 1) as f64 / m.rate;
            let frames_at = |rate: f64| (span * rate).round().max(1.0) + 1.0;
            let source = source_rate(&animation, c);
            println!(
                "| {name} | {} | {:.1} Hz ({} frames) | {:.2}x | {:.2}x ({:.0} Hz) |",
                cells.join(" | "),
                m.rate,
                m.frames,
                m.frames as f64 / frames_at(30.0),
                m.frames as f64 / frames_at(source),
                source
            );
            lines.push(Line { label: name, points });
        }
    }
    if let Some(chart) = chart {
        plot::log_log(
            Path::new(&chart),
            "Worst rotation error between baked frames (nlerp, local textures, every joint, the source's slerp)",
            "rate (Hz)",
            "degrees",
            &lines,
        )
        .expect("the chart is written");
    }
}
