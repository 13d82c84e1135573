//! Grouping moving Gaussians by consistency of rigid motion: sequential RANSAC (Fischler &
//! Bolles 1981) over whole trajectories, as multi-body motion segmentation does for tracked
//! points. A hypothesis is one rigid motion per frame fitted ([`super::rigid::fit`]) to a
//! few spatial neighbours of a random seed Gaussian; its support is the Gaussians whose RMS
//! distance to the hypothesis over the frames is within the tolerance. The best hypothesis is
//! refined on its support (refit and re-select until the support settles), taken out as a group, and the
//! search repeats on what is left. Groups whose union fits one motion are merged afterwards
//! (one object found as two pieces).

use glam::DVec3;
use rayon::prelude::*;
use splatbridge_scene::rng::Rng;

use super::rigid::{fit, Rigid};

/// Trajectories: `pos[f][i]` is Gaussian `i`'s mean in frame `f`, in f64.
pub struct Trajectories {
    pub pos: Vec<Vec<DVec3>>,
}

impl Trajectories {
    pub fn frames(&self) -> usize {
        self.pos.len()
    }

    /// Squared RMS over `frames` of `|M_f(ref) − p_f(i)|`, stopping early (returning
    /// infinity) once it must exceed `limit2`.
    pub fn msd(
        &self,
        motions: &[Rigid],
        frames: &[usize],
        reference: DVec3,
        i: usize,
        limit2: f64,
    ) -> f64 {
        let budget = limit2 * frames.len() as f64;
        let mut sum = 0.0;
        for &f in frames {
            sum += (motions[f].apply(reference) - self.pos[f][i]).length_squared();
            if sum > budget {
                return f64::INFINITY;
            }
        }
        sum / frames.len().max(1) as f64
    }

    /// One motion per frame carrying the references `refs` (of Gaussians `idx`) to their
    /// positions in that frame.
    pub fn fit_motions(&self, idx: &[u32], refs: &[DVec3]) -> Vec<Rigid> {
        (0..self.frames())
            .into_par_iter()
            .map(|f| {
                let p = &self.pos[f];
                fit(idx.iter().zip(refs).map(|(&i, &r)| (r, p[i as usize])))
            })
            .collect()
    }
}

/// Knobs of the search.
#[derive(Clone, Copy, Debug)]
pub struct Search {
    pub tolerance: f64,
    pub min_group: usize,
    pub max_groups: usize,
    pub hypotheses: usize,
    pub seed: u64,
}

/// Gaussians of one group and their motions (frame 0's positions to every frame).
pub struct Found {
    pub members: Vec<u32>,
    pub motions: Vec<Rigid>,
}

/// Neighbours a minimal sample is drawn from, and the sample's size. Six points over-determine
/// the six degrees of freedom, which steadies the rotation of small, noisy neighbourhoods; 256
/// neighbours spread the sample over a good part of an object (a wider base, a steadier
/// rotation) while most seeds still draw from one object only.
const NEIGHBOURS: usize = 256;
/// Refinement rounds at most (each refits on the support and re-selects; it stops as soon as
/// the support no longer changes).
const REFINE_ROUNDS: usize = 10;
const SAMPLE: usize = 6;
/// Gaussians a hypothesis is scored on, and the frames it is scored at (evenly spread): enough
/// to tell a group of a few dozen Gaussians from chance, at a bounded cost per hypothesis.
const SCORE_POINTS: usize = 2048;
const SCORE_FRAMES: usize = 16;

/// Find groups among `moving` (indices into the trajectories). Returns the groups, largest
/// support first, and leaves what fits none in the returned remainder.
pub fn find_groups(tr: &Trajectories, moving: &[u32], s: &Search) -> (Vec<Found>, Vec<u32>) {
    let nf = tr.frames();
    let all_frames: Vec<usize> = (0..nf).collect();
    let score_frames: Vec<usize> = if nf <= SCORE_FRAMES {
        all_frames.clone()
    } else {
        (0..SCORE_FRAMES)
            .map(|k| k * (nf - 1) / (SCORE_FRAMES - 1))
            .collect()
    };
    let tol2 = s.tolerance * s.tolerance;
    let mut rng = Rng::new(s.seed);
    let mut remaining: Vec<u32> = moving.to_vec();
    let mut groups = Vec::new();
    while remaining.len() >= s.min_group.max(SAMPLE) && groups.len() < s.max_groups {
        let scoring: Vec<u32> = if remaining.len() <= SCORE_POINTS {
            remaining.clone()
        } else {
            (0..SCORE_POINTS)
                .map(|_| remaining[rng.below(remaining.len() as u64) as usize])
                .collect()
        };
        let seeds: Vec<(u64, usize)> = (0..s.hypotheses)
            .map(|_| (rng.next_u64(), rng.below(remaining.len() as u64) as usize))
            .collect();
        let best = seeds
            .par_iter()
            .map(|&(h_seed, seed)| {
                let motions = hypothesis(tr, &remaining, seed, h_seed);
                let support = scoring
                    .iter()
                    .filter(|&&i| {
                        let r = tr.pos[0][i as usize];
                        tr.msd(&motions, &score_frames, r, i as usize, tol2) <= tol2
                    })
                    .count();
                (support, motions)
            })
            .max_by_key(|(support, _)| *support);
        let Some((_, mut motions)) = best else { break };
        let mut members = support_of(tr, &remaining, &motions, &all_frames, tol2);
        for _ in 0..REFINE_ROUNDS {
            if members.len() < SAMPLE {
                break;
            }
            let refs: Vec<DVec3> = members.iter().map(|&i| tr.pos[0][i as usize]).collect();
            motions = tr.fit_motions(&members, &refs);
            let next = support_of(tr, &remaining, &motions, &all_frames, tol2);
            let same = next == members;
            members = next;
            if same {
                break;
            }
        }
        if members.len() < s.min_group.max(SAMPLE) {
            break;
        }
        let taken: std::collections::HashSet<u32> = members.iter().copied().collect();
        remaining.retain(|i| !taken.contains(i));
        groups.push(Found { members, motions });
    }
    let (groups, dropped) = merge(tr, groups, tol2);
    remaining.extend(dropped);
    remaining.sort_unstable();
    (groups, remaining)
}

/// The members of `pool` within the tolerance of `motions` over `frames`.
fn support_of(
    tr: &Trajectories,
    pool: &[u32],
    motions: &[Rigid],
    frames: &[usize],
    tol2: f64,
) -> Vec<u32> {
    pool.par_iter()
        .copied()
        .filter(|&i| tr.msd(motions, frames, tr.pos[0][i as usize], i as usize, tol2) <= tol2)
        .collect()
}

/// One hypothesis: the seed's nearest neighbours in frame 0, a random sample of them (the
/// seed included), one fit per frame.
fn hypothesis(tr: &Trajectories, pool: &[u32], seed: usize, h_seed: u64) -> Vec<Rigid> {
    let p0 = &tr.pos[0];
    let centre = p0[pool[seed] as usize];
    let mut near: Vec<(f64, u32)> = pool
        .iter()
        .map(|&i| ((p0[i as usize] - centre).length_squared(), i))
        .collect();
    let k = NEIGHBOURS.min(near.len());
    if k < near.len() {
        near.select_nth_unstable_by(k, |a, b| a.0.total_cmp(&b.0));
        near.truncate(k);
    }
    let mut rng = Rng::new(h_seed);
    let mut sample = vec![pool[seed]];
    for _ in 1..SAMPLE.min(near.len()) {
        sample.push(near[rng.below(near.len() as u64) as usize].1);
    }
    let refs: Vec<DVec3> = sample.iter().map(|&i| p0[i as usize]).collect();
    (0..tr.frames())
        .map(|f| {
            fit(sample
                .iter()
                .zip(&refs)
                .map(|(&i, &r)| (r, tr.pos[f][i as usize])))
        })
        .collect()
}

/// Merge pairs of groups that one motion explains: the union is refitted, and the pair merges
/// when at least 95 % of the union stays within the tolerance (a real second object leaves
/// its whole side outside, far below that). The few that do not fit the merged motion are
/// returned for the per-frame remainder.
fn merge(tr: &Trajectories, mut groups: Vec<Found>, tol2: f64) -> (Vec<Found>, Vec<u32>) {
    let all: Vec<usize> = (0..tr.frames()).collect();
    let mut dropped = Vec::new();
    'again: loop {
        for a in 0..groups.len() {
            for b in a + 1..groups.len() {
                let union: Vec<u32> = groups[a]
                    .members
                    .iter()
                    .chain(&groups[b].members)
                    .copied()
                    .collect();
                let refs: Vec<DVec3> = union.iter().map(|&i| tr.pos[0][i as usize]).collect();
                let motions = tr.fit_motions(&union, &refs);
                let kept = support_of(tr, &union, &motions, &all, tol2);
                if kept.len() as f64 >= 0.95 * union.len() as f64 {
                    let keep: std::collections::HashSet<u32> = kept.iter().copied().collect();
                    dropped.extend(union.iter().filter(|&&i| !keep.contains(&i)));
                    groups.remove(b);
                    groups[a] = Found {
                        members: kept,
                        motions,
                    };
                    continue 'again;
                }
            }
        }
        return (groups, dropped);
    }
}
