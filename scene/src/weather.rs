//! Weather particles: rain and snow as Gaussians with parametric trajectories, generated for any
//! time from a seed (the seeds' "weather particles with parametric trajectories").
//!
//! Particle `i` has a base position `p₀ᵢ` in the volume, a speed factor and two drift phases,
//! all drawn from `Rng::new(seed ⊕ i)`; at time t it sits at
//! `wrap(p₀ᵢ + (down·fall·kᵢ + wind)·t + turbulence·(sin(ω₁t+φ₁), 0, sin(ω₂t+φ₂)))`, wrapped into
//! the volume per axis so the count stays constant. The same (seed, t) always gives the same
//! particles, independent of which other times were generated. Rain streaks are elongated along
//! their velocity (length = speed × 1/60 s, a typical exposure); snow flakes are small discs.

use glam::{Mat3, Quat, Vec3};
use rayon::prelude::*;

use crate::effects::{Weather, WeatherKind};
use crate::rng::Rng;
use crate::GaussianCloud;

/// Exposure that sets the visible streak length of rain, seconds.
const STREAK_SECONDS: f32 = 1.0 / 60.0;

/// Particles of `w` at time `t` inside the box `[lo, hi]` (resolved by the caller from the
/// declared volume), as an SH-degree-0 cloud.
pub fn particles(w: &Weather, t: f64, lo: Vec3, hi: Vec3) -> GaussianCloud {
    let extent = (hi - lo).max(Vec3::splat(1e-9));
    let n = w.count as usize;
    let down = Vec3::Y;
    let wind = Vec3::from(w.wind);
    let (colour, opacity) = match w.kind {
        WeatherKind::Rain => (Vec3::new(0.72, 0.76, 0.82), 0.35),
        WeatherKind::Snow => (Vec3::new(0.95, 0.95, 0.97), 0.85),
    };
    // Time modulo a long period keeps the sine arguments and positions well conditioned at
    // t = 1e5 s: positions wrap anyway, so only the drift's phase needs care.
    let tf = t as f32;
    let rows: Vec<(Vec3, Vec3, Quat)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut r = Rng::new(w.seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ i as u64);
            let p0 = lo + Vec3::new(r.f32(), r.f32(), r.f32()) * extent;
            let k = r.range(0.8, 1.2);
            let (w1, w2) = (r.range(0.5, 2.0), r.range(0.5, 2.0));
            let (ph1, ph2) = (
                r.range(0.0, std::f32::consts::TAU),
                r.range(0.0, std::f32::consts::TAU),
            );
            let vel = down * w.fall_speed * k + wind;
            // Displacement computed in f64 so that t = 1e5 s does not lose the sub-unit part.
            let disp = vel.as_dvec3() * t;
            let drift = Vec3::new(
                ((w1 as f64 * t + ph1 as f64).sin()) as f32,
                0.0,
                ((w2 as f64 * t + ph2 as f64).sin()) as f32,
            ) * w.turbulence;
            let rel = (p0 - lo).as_dvec3() + disp + drift.as_dvec3();
            let e = extent.as_dvec3();
            let wrapped = glam::DVec3::new(
                rel.x.rem_euclid(e.x),
                rel.y.rem_euclid(e.y),
                rel.z.rem_euclid(e.z),
            );
            let pos = lo + wrapped.as_vec3().min(extent);
            let (scale, rot) = match w.kind {
                WeatherKind::Rain => {
                    let speed = vel.length();
                    let len = (speed * STREAK_SECONDS).max(w.size);
                    let dir = if speed > 0.0 { vel / speed } else { down };
                    (
                        Vec3::new(len, w.size * 0.3, w.size * 0.3),
                        rotation_x_to(dir),
                    )
                }
                WeatherKind::Snow => {
                    let axis = Vec3::new(r.normal(), r.normal(), r.normal()).normalize_or(Vec3::Y);
                    let spin =
                        Quat::from_axis_angle(axis, r.range(0.0, std::f32::consts::TAU) + 0.3 * tf);
                    (Vec3::new(w.size, w.size, w.size * 0.25), spin)
                }
            };
            (pos, scale, rot)
        })
        .collect();
    let mut cloud = GaussianCloud::with_capacity(0, n);
    for (pos, scale, rot) in rows {
        cloud.push_activated(pos, scale, rot, opacity, colour);
    }
    cloud
}

/// A rotation taking local +x to `dir`.
fn rotation_x_to(dir: Vec3) -> Quat {
    let x = dir.normalize_or(Vec3::Y);
    let helper = if x.z.abs() < 0.9 { Vec3::Z } else { Vec3::X };
    let y = helper.cross(x).normalize();
    let z = x.cross(y);
    Quat::from_mat3(&Mat3::from_cols(x, y, z)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::WeatherVolume;

    fn rain(seed: u64) -> Weather {
        Weather {
            kind: WeatherKind::Rain,
            count: 500,
            seed,
            fall_speed: 8.0,
            wind: [1.0, 0.0, 0.0],
            turbulence: 0.05,
            size: 0.01,
            volume: WeatherVolume::Scene,
        }
    }

    #[test]
    fn particles_are_deterministic_and_inside_the_volume() {
        let (lo, hi) = (Vec3::new(-5.0, -3.0, -5.0), Vec3::new(5.0, 0.0, 5.0));
        let a = particles(&rain(3), 1.25, lo, hi);
        let b = particles(&rain(3), 1.25, lo, hi);
        assert_eq!(a, b);
        let c = particles(&rain(4), 1.25, lo, hi);
        assert_ne!(a.means, c.means);
        for m in &a.means {
            assert!(m.cmpge(lo).all() && m.cmple(hi).all(), "{m}");
        }
        let far = particles(&rain(3), 1e5, lo, hi);
        assert!(far
            .means
            .iter()
            .all(|m| m.is_finite() && m.cmpge(lo).all() && m.cmple(hi).all()));
    }

    #[test]
    fn rain_streaks_point_along_velocity() {
        let (lo, hi) = (Vec3::splat(-10.0), Vec3::splat(10.0));
        let c = particles(&rain(1), 0.0, lo, hi);
        let q = c.unit_rotation(0);
        let long_axis = q * Vec3::X;
        let expected_dir = Vec3::new(1.0, 8.0, 0.0).normalize();
        // Per-particle speed factors change the magnitude, not the direction, only when wind is
        // zero; with wind the direction varies by at most atan(1/6.4) − atan(1/9.6) ≈ 3°.
        assert!(
            long_axis.angle_between(expected_dir).abs().to_degrees() < 3.5
                || long_axis.angle_between(-expected_dir).to_degrees() < 3.5
        );
        let s = c.scale(0);
        assert!(s.x > 5.0 * s.y);
    }
}
