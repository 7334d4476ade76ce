//! What every evaluator writes: the order of samples ([`Layout`]), the f64 reference's
//! [`Output`], and the fast paths' float32 rows ([`FloatOutput`], each sample a [`Row`]).
//! One definition of the row, read by the CPU kernels, the GPU's host side, the CLI's files
//! and Python.

use crate::sampling::SampleTimes;
use quatcurve_core::quat::QuatF64;
use std::ops::Range;

/// Order of samples in the output arrays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Layout {
    /// Track 0's samples, then track 1's, ...
    #[default]
    Track,
    /// All tracks at frame 0, then all at frame 1, ... (an animation texture). Needs the same
    /// sample count in every track.
    Frame,
}

impl Layout {
    /// Where sample `j` of track `track` lands in the output, counted in samples.
    #[must_use]
    pub fn slot(self, times: &SampleTimes, track: usize, j: usize) -> usize {
        match self {
            Layout::Track => times.offsets()[track] + j,
            Layout::Frame => j * times.track_count() + track,
        }
    }
}

/// Evaluated samples; derivative arrays are empty unless requested.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Output {
    /// Unit rotations `[x, y, z, w]`, sign-continuous within each track.
    pub rotations: Vec<[f64; 4]>,
    /// Body angular velocities (rad per unit time).
    pub angular_velocity: Vec<[f64; 3]>,
    /// Body angular accelerations.
    pub angular_acceleration: Vec<[f64; 3]>,
}

impl Output {
    /// The samples as f64 rows laid out as [`Row`]s without matrices (rotation, then omega
    /// and alpha when the output has them).
    #[must_use]
    pub fn to_rows(&self) -> Vec<f64> {
        let derivatives = !self.angular_velocity.is_empty();
        let mut data = Vec::with_capacity(self.rotations.len() * Row { derivatives, matrix: false }.channels());
        for (i, q) in self.rotations.iter().enumerate() {
            data.extend_from_slice(q);
            if derivatives {
                data.extend_from_slice(&self.angular_velocity[i]);
                data.extend_from_slice(&self.angular_acceleration[i]);
            }
        }
        data
    }
}

/// Where each quantity sits in a float32 output row (DESIGN section 5): the rotation `x, y,
/// z, w`; with derivatives the body angular velocity, then the acceleration; with a matrix its
/// nine entries, row-major. The CPU kernels, the GPU's output (the stores at the end of
/// `evaluate` in `shaders/eval.wgsl`, checked against this by the GPU tests), the `.npy`
/// files and Python all read it from here.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Row {
    /// Omega and alpha follow the rotation.
    pub derivatives: bool,
    /// The rotation matrix comes last.
    pub matrix: bool,
}

impl Row {
    /// The rotation `x, y, z, w`.
    pub const ROTATION: Range<usize> = 0..4;
    /// Body angular velocity (with derivatives).
    pub const OMEGA: Range<usize> = 4..7;
    /// Body angular acceleration (with derivatives).
    pub const ALPHA: Range<usize> = 7..10;

    /// The row-major 3x3 matrix (with a matrix).
    #[must_use]
    pub fn matrix(self) -> Range<usize> {
        let at = if self.derivatives { Self::ALPHA.end } else { Self::ROTATION.end };
        at..at + 9
    }

    /// Floats per row.
    #[must_use]
    pub fn channels(self) -> usize {
        if self.matrix {
            self.matrix().end
        } else if self.derivatives {
            Self::ALPHA.end
        } else {
            Self::ROTATION.end
        }
    }

    /// Writes one sample into `row` (of [`Row::channels`] floats); `omega` and `alpha` are
    /// read only with derivatives.
    #[inline(always)]
    pub fn write(self, row: &mut [f32], q: [f32; 4], omega: [f32; 3], alpha: [f32; 3]) {
        row[Self::ROTATION].copy_from_slice(&q);
        if self.derivatives {
            row[Self::OMEGA].copy_from_slice(&omega);
            row[Self::ALPHA].copy_from_slice(&alpha);
        }
        self.fill_matrix(row);
    }

    /// With a matrix: forms it from the row's rotation (in f64, then rounded), for kernels
    /// that write the rotation themselves.
    #[inline(always)]
    pub fn fill_matrix(self, row: &mut [f32]) {
        if self.matrix {
            let q = &row[Self::ROTATION];
            let m = QuatF64::from_array([q[0], q[1], q[2], q[3]].map(f64::from)).to_mat3();
            for (o, v) in row[self.matrix()].iter_mut().zip(m.iter().flatten()) {
                *o = *v as f32;
            }
        }
    }
}

/// Floats per joint and frame of a local-transform texture row (`bake --texture local`, and
/// the input of forward kinematics on either device): rotation `x, y, z, w`, translation,
/// scale, parent-relative.
pub const LOCAL_CHANNELS: usize = 10;
/// Floats per joint and frame of a matrix texture row (`--texture model|skin`, the output of
/// forward kinematics): a 3x4 row-major matrix.
pub const MATRIX_CHANNELS: usize = 12;
/// Floats per vertex and frame of skinned mesh vertices (the input and output of mesh
/// skinning on either device): position, normal.
pub const VERTEX_CHANNELS: usize = 6;

/// Float32 samples of the fast paths (GPU, CPU): `samples x channels` in the requested
/// layout, each sample a [`Row`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FloatOutput {
    /// Floats per sample.
    pub channels: usize,
    /// The samples.
    pub data: Vec<f32>,
}

impl FloatOutput {
    /// `samples x channels` zeros, backed by huge pages where the OS offers them.
    #[must_use]
    pub fn zeroed(samples: usize, channels: usize) -> Self {
        let mut data = vec![0.0f32; samples * channels];
        prefault(&mut data);
        Self { channels, data }
    }

    /// The rows of an f64 [`Output`], rounded to f32: the rotation, then omega and alpha when
    /// the output has them, then the matrix when `matrix` (from the rounded rotation, as the
    /// fast paths form it).
    #[must_use]
    pub fn from_output(out: &Output, matrix: bool) -> Self {
        let row = Row { derivatives: !out.angular_velocity.is_empty(), matrix };
        let channels = row.channels();
        let mut data = vec![0.0; out.rotations.len() * channels];
        let f32s = |v: &[f64]| -> [f32; 3] { [v[0] as f32, v[1] as f32, v[2] as f32] };
        for (i, (q, dst)) in out.rotations.iter().zip(data.chunks_exact_mut(channels)).enumerate() {
            let (omega, alpha) = if row.derivatives {
                (f32s(&out.angular_velocity[i]), f32s(&out.angular_acceleration[i]))
            } else {
                ([0.0; 3], [0.0; 3])
            };
            row.write(dst, q.map(|v| v as f32), omega, alpha);
        }
        Self { channels, data }
    }

    /// Converts to the reference's [`Output`] (f64, rotations and derivatives).
    #[must_use]
    pub fn to_output(&self, derivatives: bool) -> Output {
        let mut out = Output::default();
        let wide = |v: &[f32]| -> [f64; 3] { [v[0], v[1], v[2]].map(f64::from) };
        for row in self.data.chunks_exact(self.channels) {
            let q = &row[Row::ROTATION];
            out.rotations.push([q[0], q[1], q[2], q[3]].map(f64::from));
            if derivatives {
                out.angular_velocity.push(wide(&row[Row::OMEGA]));
                out.angular_acceleration.push(wide(&row[Row::ALPHA]));
            }
        }
        out
    }
}

/// Backs a large, fresh output with transparent huge pages and faults it in now, from every
/// core at once. The allocation is lazily zeroed memory: touched 4 KiB page by page by the
/// evaluation, it cost a page fault each, as much time as the evaluation itself for a 160 MB
/// output; huge pages touched by one thread (the GPU path's copy-out) sometimes stalled for
/// 300 ms. `MADV_POPULATE_WRITE` in parallel pieces faults 160 MB in about 4 ms here. Both
/// are hints: on an older kernel they fail harmlessly and the pages fault in lazily.
#[allow(unsafe_code)]
fn prefault(data: &mut [f32]) {
    #[cfg(target_os = "linux")]
    {
        use rayon::prelude::*;
        const HUGE: usize = 2 << 20;
        let (start, len) = (data.as_mut_ptr() as usize, std::mem::size_of_val(data));
        if len < 4 * HUGE {
            return;
        }
        let aligned = start.next_multiple_of(HUGE);
        let end = (start + len) / HUGE * HUGE;
        // SAFETY: every range below lies inside `data`, which we own mutably and which holds
        // zeros; MADV_HUGEPAGE changes how the kernel backs the pages and MADV_POPULATE_WRITE
        // only faults them in (contents stay zero). Failures leave the memory as it was.
        unsafe {
            libc::madvise(aligned as *mut libc::c_void, end - aligned, libc::MADV_HUGEPAGE);
        }
        let pieces = (end - aligned) / HUGE;
        let per = pieces.div_ceil(4 * rayon::current_num_threads()).max(1);
        (0..pieces.div_ceil(per)).into_par_iter().for_each(|i| {
            let from = aligned + i * per * HUGE;
            let to = (from + per * HUGE).min(end);
            // SAFETY: as above.
            unsafe {
                libc::madvise(from as *mut libc::c_void, to - from, libc::MADV_POPULATE_WRITE);
            }
        });
    }
    #[cfg(not(target_os = "linux"))]
    let _ = data;
}
