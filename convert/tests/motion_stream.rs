//! The streamed decomposition (`motion::stream`: frames read one at a time, only the moving
//! Gaussians' trajectories held) against the in-memory one (`motion::decompose`, every frame
//! held), its reference: the same labels, groups, poses and scene on sequences with known
//! motion, and the frames read a bounded number of times.

use std::borrow::Cow;
use std::sync::atomic::{AtomicUsize, Ordering};

use splatbridge_convert::motion::stream::{decompose_streamed, FrameSource};
use splatbridge_convert::motion::{decompose, DecomposeOptions};
use splatbridge_convert::Result;
use splatbridge_scene::fixtures::moving::{moving_cutouts, MovingParams};
use splatbridge_scene::GaussianCloud;

/// Frames handed out as fresh copies (as a reader does), counting the reads.
struct Reading<'a> {
    frames: &'a [GaussianCloud],
    reads: AtomicUsize,
}

impl FrameSource for Reading<'_> {
    fn len(&self) -> usize {
        self.frames.len()
    }
    fn frame(&self, f: usize) -> Result<Cow<'_, GaussianCloud>> {
        self.reads.fetch_add(1, Ordering::Relaxed);
        Ok(Cow::Owned(self.frames[f].clone()))
    }
}

fn same(params: &MovingParams, opts: &DecomposeOptions) {
    let base = splatbridge_scene::fixtures::large(20_000, 5);
    let (frames, times, _) = moving_cutouts(&base, params);
    let d = decompose(&frames, &times, opts).unwrap();
    let src = Reading {
        frames: &frames,
        reads: AtomicUsize::new(0),
    };
    let s = decompose_streamed(&src, &times, opts).unwrap();
    let sd = &s.decomposition;
    assert_eq!(sd.labels, d.labels);
    // The same sums in the same order: bit-equal.
    assert_eq!(sd.noise.to_bits(), d.noise.to_bits());
    assert_eq!(sd.tolerance.to_bits(), d.tolerance.to_bits());
    assert_eq!(sd.groups.len(), d.groups.len());
    assert!(opts.objects == !d.groups.is_empty(), "{}", d.groups.len());
    for (a, b) in sd.groups.iter().zip(&d.groups) {
        assert_eq!(a.members, b.members);
        assert_eq!(a.rms.to_bits(), b.rms.to_bits());
        for (p, q) in a.poses.iter().zip(&b.poses) {
            assert_eq!(p.rotation, q.rotation);
            assert_eq!(p.translation, q.translation);
        }
    }
    assert_eq!(
        (sd.static_count, sd.per_frame, sd.per_frame_appearance),
        (d.static_count, d.per_frame, d.per_frame_appearance)
    );
    // The in-memory decomposition sums this report figure in parallel (rayon's order), the
    // streamed one frame by frame: equal to a few ulps (measured 2).
    assert!(
        (sd.per_frame_motion_rms - d.per_frame_motion_rms).abs()
            <= 1e-12 * d.per_frame_motion_rms.max(1e-30),
        "{} vs {}",
        sd.per_frame_motion_rms,
        d.per_frame_motion_rms
    );
    // The static RMS is taken from distances to frame 0 (one pass) rather than to the mean
    // (two): equal to f64 rounding of sums of ~1e-8 over ~1e5 terms.
    assert!(
        (sd.static_rms - d.static_rms).abs() <= 1e-9 * d.static_rms.max(1e-30),
        "{} vs {}",
        sd.static_rms,
        d.static_rms
    );
    let mut seen = Vec::new();
    let a = s
        .to_scene(&src, &times, params.fps, |f, _| seen.push(f))
        .unwrap();
    let b = d.to_scene(&frames, &times, params.fps).unwrap();
    assert_eq!(seen, (0..frames.len()).collect::<Vec<_>>());
    // Frame 0 twice and three passes (two with objects off): the frames are never all held.
    let passes = if opts.objects { 3 } else { 2 };
    assert_eq!(src.reads.load(Ordering::Relaxed), passes * frames.len() + 1);
    assert_eq!(a.static_gaussians.means, b.static_gaussians.means);
    assert_eq!(a.static_gaussians.sh, b.static_gaussians.sh);
    assert_eq!(a.objects.len(), b.objects.len());
    for (x, y) in a.objects.iter().zip(&b.objects) {
        assert_eq!(x.gaussians.means, y.gaussians.means);
        assert_eq!(x.gaussians.rotations, y.gaussians.rotations);
        assert_eq!(x.gaussians.sh, y.gaussians.sh);
        assert_eq!(x.track.keys.len(), y.track.keys.len());
    }
    assert_eq!(a.frames.len(), b.frames.len());
    for (x, y) in a.frames.iter().zip(&b.frames) {
        assert_eq!(x.t, y.t);
        assert_eq!(x.gaussians.means, y.gaussians.means);
    }
}

#[test]
fn streamed_equals_in_memory_with_objects() {
    same(
        &MovingParams {
            objects: 3,
            frames: 12,
            ..MovingParams::default()
        },
        &DecomposeOptions::default(),
    );
}

#[test]
fn streamed_equals_in_memory_without_objects() {
    same(
        &MovingParams {
            objects: 2,
            frames: 6,
            ..MovingParams::default()
        },
        &DecomposeOptions {
            objects: false,
            ..DecomposeOptions::default()
        },
    );
}

#[test]
fn streamed_refuses_what_the_in_memory_one_refuses() {
    let base = splatbridge_scene::fixtures::large(500, 5);
    let (mut frames, times, _) = moving_cutouts(
        &base,
        &MovingParams {
            objects: 1,
            frames: 4,
            ..MovingParams::default()
        },
    );
    frames[2].means[7].x = f32::NAN;
    let err = decompose_streamed(&frames[..], &times, &DecomposeOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("frame 2") && err.contains("Gaussian 7"),
        "{err}"
    );
    frames[2].means[7].x = 0.0;
    frames[3].retain_indices(|i| i != 3);
    let err = decompose_streamed(&frames[..], &times, &DecomposeOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("frame 3 has 499"), "{err}");
    let err = decompose_streamed(&frames[..3], &times, &DecomposeOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("3 frames but 4 times"), "{err}");
}
