use quatcurve::gpu::*;
use quatcurve::*;
fn main() {
    let spec = CurveSpec { tangents: Tangents::Zero, ..CurveSpec::new(Curve::Slerp) };
    let count = 1400;
    let rotations: Vec<[f64;4]> = (0..count).map(|i| DQuat::exp(DVec3::new(0.3*(i as f64*0.7).sin(), 0.2*(i as f64*1.3).cos(), 0.1)).to_array()).collect();
    let t = Track { times: Some((0..count).map(|i| 1000.0 + i as f64 / 37.5).collect()), ..Track::from_rotations(rotations) };
    let batch = Batch::from_tracks(&[t], &spec).unwrap();
    let times = SampleTimes::uniform(&batch, Sampling::Rate(120.0)).unwrap();
    let gpu = GpuEvaluator::new().unwrap();
    let out = gpu.evaluate(&batch, &times, &GpuOptions::default()).unwrap();
    let mut worst = (0.0, 0);
    for j in 0..times.total() {
        let r = evaluate(batch.view(0), times.time(0, j)).rotation;
        let q = &out.data[j*4..j*4+4];
        let g = DQuat::from_xyzw(q[0].into(), q[1].into(), q[2].into(), q[3].into());
        let e = g.angle_to(r);
        if e > worst.0 { worst = (e, j); }
    }
    let j = worst.1;
    let t0 = times.time(0, j);
    let q = &out.data[j*4..j*4+4];
    let g = DQuat::from_xyzw(q[0].into(), q[1].into(), q[2].into(), q[3].into());
    let mut best = (1.0, 0.0);
    for k in -20000..20000 { let d = k as f64 * 1e-6; let e = g.angle_to(evaluate(batch.view(0), t0 + d).rotation); if e < best.0 { best = (e, d); } }
    println!("worst {:?} at j {} t {} ; best match offset {:?}", worst.0, j, t0, best);
    for jj in [0usize, 1, 100, 4095, 4096, 4097, 4357] { let t = times.time(0, jj); let q = &out.data[jj*4..jj*4+4];
        let g = DQuat::from_xyzw(q[0].into(), q[1].into(), q[2].into(), q[3].into());
        let mut best = (1.0, 0.0);
        for k in -2000..2000 { let d = k as f64 * 1e-5; let e = g.angle_to(evaluate(batch.view(0), t + d).rotation); if e < best.0 { best = (e, d); } }
        println!("j {jj}: err {:e} offset {:?}", g.angle_to(evaluate(batch.view(0), t).rotation), best); }
}
