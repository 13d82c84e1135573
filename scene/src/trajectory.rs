//! Rule-based trajectories for training-free editing: an inserted object's pose track generated
//! from a rule (`straight`, `lane_change`, `turn`, `stop`) or from explicit per-frame position
//! deltas `P(t+1) = P(t) + Δ(t)` with heading from velocity — the contract an external planner
//! (a language model included) can produce.
//!
//! Conventions: the world is y-down (COLMAP; up = −y) and objects drive on planes of constant y.
//! An object's local frame has +x forward, +y down, +z = x × y (right-handed), so the identity
//! rotation drives along world +x. Headings are angles in the ground plane measured from +x
//! towards +z. Lateral offsets and turn angles are positive towards +z (to the object's right
//! when looking down, left-hand side when seen from above with −y up; only the sign convention
//! matters: it is stated here and used consistently).

use glam::{Mat3, Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::dynamic::{Pose, PoseKey, Track};

/// A trajectory rule as written in a manifest object's `"trajectory"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TrajectoryRule {
    /// Constant speed along `heading_deg`.
    Straight {
        start: [f32; 3],
        #[serde(default)]
        heading_deg: f32,
        speed: f32,
    },
    /// Constant forward speed; the lateral offset follows a minimum-jerk profile
    /// (10τ³ − 15τ⁴ + 6τ⁵) from `begin` for `duration` seconds, so it ends exactly `offset` to the
    /// side with zero lateral velocity (heading continuous and back to `heading_deg`).
    LaneChange {
        start: [f32; 3],
        #[serde(default)]
        heading_deg: f32,
        speed: f32,
        offset: f32,
        begin: f64,
        duration: f64,
    },
    /// Straight until `begin`, then an arc of `radius` through `angle_deg` (positive towards +z),
    /// then straight again, at constant speed.
    Turn {
        start: [f32; 3],
        #[serde(default)]
        heading_deg: f32,
        speed: f32,
        radius: f32,
        angle_deg: f32,
        begin: f64,
    },
    /// Constant speed until `begin`, then constant deceleration to rest within `distance`;
    /// no overshoot, no reversing.
    Stop {
        start: [f32; 3],
        #[serde(default)]
        heading_deg: f32,
        speed: f32,
        begin: f64,
        distance: f32,
    },
    /// Explicit per-frame deltas: key k is at `start + Σ_{j<k} deltas[j]`, one key per frame.
    Deltas {
        start: [f32; 3],
        deltas: Vec<[f32; 3]>,
    },
}

/// What was wrong with a rule.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("trajectory: {0}")]
pub struct TrajectoryError(pub String);

fn err<T>(s: impl Into<String>) -> Result<T, TrajectoryError> {
    Err(TrajectoryError(s.into()))
}

/// Ground-plane unit vector for a heading.
pub fn heading_dir(heading_rad: f32) -> Vec3 {
    Vec3::new(heading_rad.cos(), 0.0, heading_rad.sin())
}

/// Rotation whose local +x is the ground-plane direction `forward` (local +y stays world +y).
pub fn heading_rotation(forward: Vec3) -> Quat {
    let f = Vec3::new(forward.x, 0.0, forward.z).normalize_or(Vec3::X);
    let down = Vec3::Y;
    Quat::from_mat3(&Mat3::from_cols(f, down, f.cross(down))).normalize()
}

impl TrajectoryRule {
    /// The rule's name and every number it holds (positions, angles, speeds, times), so
    /// finiteness is checked in one place.
    fn numbers(&self) -> (&'static str, Vec<f64>) {
        let v3 = |a: &[f32; 3]| a.iter().map(|&x| x as f64).collect::<Vec<_>>();
        match self {
            TrajectoryRule::Straight {
                start,
                heading_deg,
                speed,
            } => (
                "straight",
                [v3(start), vec![*heading_deg as f64, *speed as f64]].concat(),
            ),
            TrajectoryRule::LaneChange {
                start,
                heading_deg,
                speed,
                offset,
                begin,
                duration,
            } => (
                "lane_change",
                [
                    v3(start),
                    vec![
                        *heading_deg as f64,
                        *speed as f64,
                        *offset as f64,
                        *begin,
                        *duration,
                    ],
                ]
                .concat(),
            ),
            TrajectoryRule::Turn {
                start,
                heading_deg,
                speed,
                radius,
                angle_deg,
                begin,
            } => (
                "turn",
                [
                    v3(start),
                    vec![
                        *heading_deg as f64,
                        *speed as f64,
                        *radius as f64,
                        *angle_deg as f64,
                        *begin,
                    ],
                ]
                .concat(),
            ),
            TrajectoryRule::Stop {
                start,
                heading_deg,
                speed,
                begin,
                distance,
            } => (
                "stop",
                [
                    v3(start),
                    vec![*heading_deg as f64, *speed as f64, *begin, *distance as f64],
                ]
                .concat(),
            ),
            TrajectoryRule::Deltas { start, .. } => ("deltas", v3(start)),
        }
    }

    fn check(&self) -> Result<(), TrajectoryError> {
        let (name, numbers) = self.numbers();
        if numbers.iter().any(|x| !x.is_finite()) {
            return err(format!("{name}: non-finite value"));
        }
        match self {
            TrajectoryRule::LaneChange { duration, .. } if !(*duration > 0.0) => err(format!(
                "lane_change: duration must be positive, got {duration}"
            )),
            TrajectoryRule::Turn { radius, .. } if !(*radius > 0.0) => {
                err(format!("turn: radius must be positive, got {radius}"))
            }
            TrajectoryRule::Turn { speed, .. } if *speed <= 0.0 => {
                err("turn: speed must be positive")
            }
            TrajectoryRule::Stop { speed, .. } if *speed < 0.0 => {
                err("stop: speed must not be negative")
            }
            TrajectoryRule::Stop { distance, .. } if !(*distance > 0.0) => {
                err(format!("stop: distance must be positive, got {distance}"))
            }
            TrajectoryRule::Deltas { deltas, .. } if deltas.is_empty() => {
                err("deltas: at least one delta is needed")
            }
            TrajectoryRule::Deltas { deltas, .. } => {
                match deltas.iter().position(|d| d.iter().any(|x| !x.is_finite())) {
                    Some(k) => err(format!("deltas: delta {k} is not finite")),
                    None => Ok(()),
                }
            }
            _ => Ok(()),
        }
    }

    /// Position and ground-plane velocity at time `t` (analytic rules only).
    fn state(&self, t: f64) -> (Vec3, Vec3) {
        match *self {
            TrajectoryRule::Straight {
                start,
                heading_deg,
                speed,
            } => {
                let f = heading_dir(heading_deg.to_radians());
                (Vec3::from(start) + f * speed * t as f32, f * speed)
            }
            TrajectoryRule::LaneChange {
                start,
                heading_deg,
                speed,
                offset,
                begin,
                duration,
            } => {
                let f = heading_dir(heading_deg.to_radians());
                let side = Vec3::new(-f.z, 0.0, f.x);
                let tau = ((t - begin) / duration).clamp(0.0, 1.0);
                let s = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau);
                let ds = if (0.0..=1.0).contains(&((t - begin) / duration)) {
                    30.0 * tau * tau * (1.0 - tau) * (1.0 - tau) / duration
                } else {
                    0.0
                };
                let p = Vec3::from(start) + f * speed * t as f32 + side * offset * s as f32;
                (p, f * speed + side * offset * ds as f32)
            }
            TrajectoryRule::Turn {
                start,
                heading_deg,
                speed,
                radius,
                angle_deg,
                begin,
            } => {
                let h0 = heading_deg.to_radians() as f64;
                let sign = angle_deg.signum() as f64;
                let sweep = (angle_deg.abs() as f64).to_radians();
                let r = radius as f64;
                let v = speed as f64;
                let p0 = Vec3::from(start).as_dvec3();
                let dir = |h: f64| glam::DVec3::new(h.cos(), 0.0, h.sin());
                if t <= begin {
                    let p = p0 + dir(h0) * v * t;
                    return (p.as_vec3(), (dir(h0) * v).as_vec3());
                }
                let pb = p0 + dir(h0) * v * begin;
                // Centre of the arc: to the +z-ward side (sign > 0) of the heading.
                let normal = glam::DVec3::new(-h0.sin(), 0.0, h0.cos()) * sign;
                let centre = pb + normal * r;
                let arc_time = sweep * r / v;
                let ta = (t - begin).min(arc_time);
                let phi = sign * v * ta / r;
                let h = h0 + phi;
                let p = centre - glam::DVec3::new(-h.sin(), 0.0, h.cos()) * sign * r;
                if t - begin <= arc_time {
                    return (p.as_vec3(), (dir(h) * v).as_vec3());
                }
                let p = p + dir(h) * v * (t - begin - arc_time);
                (p.as_vec3(), (dir(h) * v).as_vec3())
            }
            TrajectoryRule::Stop {
                start,
                heading_deg,
                speed,
                begin,
                distance,
            } => {
                let f = heading_dir(heading_deg.to_radians()).as_dvec3();
                let v = speed as f64;
                let p0 = Vec3::from(start).as_dvec3();
                if v == 0.0 {
                    return (p0.as_vec3(), Vec3::ZERO);
                }
                if t <= begin {
                    return ((p0 + f * v * t).as_vec3(), (f * v).as_vec3());
                }
                let a = v * v / (2.0 * distance as f64);
                let t_stop = v / a;
                let dt = (t - begin).min(t_stop);
                let s = v * dt - 0.5 * a * dt * dt;
                let vel = (v - a * dt).max(0.0);
                ((p0 + f * (v * begin + s)).as_vec3(), (f * vel).as_vec3())
            }
            TrajectoryRule::Deltas { .. } => unreachable!("deltas are sampled per frame"),
        }
    }

    /// The pose track over `[start, end]` at `fps` keys per second. Heading follows the velocity;
    /// where the object is at rest the last heading is kept.
    pub fn track(&self, start: f64, end: f64, fps: f64) -> Result<Track, TrajectoryError> {
        self.check()?;
        if !(fps > 0.0 && fps.is_finite() && end >= start && start.is_finite() && end.is_finite()) {
            return err(format!(
                "time range {start}..{end} at {fps} fps is not usable"
            ));
        }
        let mut keys = Vec::new();
        if let TrajectoryRule::Deltas { start: p0, deltas } = self {
            let mut p = Vec3::from(*p0);
            let mut heading = Vec3::X;
            for k in 0..=deltas.len() {
                let v = if k < deltas.len() {
                    Vec3::from(deltas[k])
                } else {
                    Vec3::from(deltas[k - 1])
                };
                if v.x.hypot(v.z) > 1e-9 {
                    heading = v;
                }
                keys.push(PoseKey {
                    t: start + k as f64 / fps,
                    pose: Pose {
                        translation: p,
                        rotation: heading_rotation(heading),
                    },
                });
                if k < deltas.len() {
                    p += Vec3::from(deltas[k]);
                }
            }
            return Ok(Track { keys });
        }
        let n = ((end - start) * fps).round().max(0.0) as usize;
        let h0 = match self {
            TrajectoryRule::Straight { heading_deg, .. }
            | TrajectoryRule::LaneChange { heading_deg, .. }
            | TrajectoryRule::Turn { heading_deg, .. }
            | TrajectoryRule::Stop { heading_deg, .. } => heading_dir(heading_deg.to_radians()),
            TrajectoryRule::Deltas { .. } => Vec3::X,
        };
        let mut heading = h0;
        for k in 0..=n {
            let t = if k == n { end } else { start + k as f64 / fps };
            let (p, v) = self.state(t - start);
            if v.x.hypot(v.z) > 1e-9 {
                heading = v;
            }
            keys.push(PoseKey {
                t,
                pose: Pose {
                    translation: p,
                    rotation: heading_rotation(heading),
                },
            });
        }
        Ok(Track { keys })
    }
}

/// Retiming of an object's motion (training-free editing): the object plays its track `scale`
/// times as fast, `offset` seconds later. A key at original time `τ` moves to
/// `start + (τ − start)/scale + offset`, where `start` is the scene's start time, so the pose
/// at scene time `t` is the original pose at `start + (t − offset − start)·scale`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Retime {
    #[serde(default)]
    pub offset: f64,
    #[serde(default = "one")]
    pub scale: f64,
}

fn one() -> f64 {
    1.0
}

impl Retime {
    /// Check finite values and a positive scale; the message names the field.
    pub fn check(&self) -> Result<(), TrajectoryError> {
        if !self.offset.is_finite() {
            return err(format!("retime.offset = {} is not finite", self.offset));
        }
        if !(self.scale > 0.0 && self.scale.is_finite()) {
            return err(format!(
                "retime.scale = {} must be positive and finite",
                self.scale
            ));
        }
        Ok(())
    }

    /// The retimed track (key times mapped as in the type's docs; poses unchanged).
    pub fn apply(&self, track: &Track, start: f64) -> Result<Track, TrajectoryError> {
        self.check()?;
        let keys: Vec<PoseKey> = track
            .keys
            .iter()
            .map(|k| PoseKey {
                t: start + (k.t - start) / self.scale + self.offset,
                pose: k.pose,
            })
            .collect();
        if let Some(i) = (1..keys.len()).find(|&i| !(keys[i].t > keys[i - 1].t)) {
            return err(format!(
                "retime: keys {} and {i} collapse to the same time (scale too large for the key spacing)",
                i - 1
            ));
        }
        Ok(Track { keys })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn forward(q: Quat) -> Vec3 {
        q * Vec3::X
    }

    #[test]
    fn lane_change_ends_in_target_lane_with_continuous_heading() {
        let r = TrajectoryRule::LaneChange {
            start: [0.0, 0.0, 0.0],
            heading_deg: 0.0,
            speed: 10.0,
            offset: 3.5,
            begin: 1.0,
            duration: 2.0,
        };
        let tr = r.track(0.0, 4.0, 50.0).unwrap();
        let last = tr.keys.last().unwrap().pose;
        // Exact arithmetic of the quintic at τ = 1 gives offset exactly; f32 sums leave ~1e-6.
        assert!((last.translation.z - 3.5).abs() < 1e-4);
        assert!((forward(last.rotation) - Vec3::X).length() < 1e-5);
        // Heading changes by less than the per-frame bound of a smooth manoeuvre: the maximum
        // lateral speed is 1.875·offset/duration ≈ 3.3 m/s against 10 m/s forward, so the heading
        // never exceeds atan(0.33) ≈ 18° and moves by well under 2° per 20 ms frame.
        for w in tr.keys.windows(2) {
            let a = forward(w[0].pose.rotation);
            let b = forward(w[1].pose.rotation);
            assert!(a.angle_between(b).to_degrees() < 2.0);
        }
    }

    #[test]
    fn turn_follows_its_radius() {
        let r = TrajectoryRule::Turn {
            start: [0.0, 0.0, 0.0],
            heading_deg: 0.0,
            speed: 5.0,
            radius: 10.0,
            angle_deg: 90.0,
            begin: 1.0,
        };
        let tr = r.track(0.0, 6.0, 25.0).unwrap();
        let centre = Vec3::new(5.0, 0.0, 10.0);
        let arc_time = std::f64::consts::FRAC_PI_2 * 10.0 / 5.0;
        for k in &tr.keys {
            if k.t >= 1.0 && k.t <= 1.0 + arc_time {
                let d = (k.pose.translation - centre).length();
                assert!((d - 10.0).abs() < 1e-4, "t={} radius {d}", k.t);
            }
        }
        let last = tr.keys.last().unwrap().pose;
        assert!((forward(last.rotation) - Vec3::Z).length() < 1e-4);
    }

    #[test]
    fn stop_comes_to_rest_without_overshoot() {
        let r = TrajectoryRule::Stop {
            start: [0.0, 0.0, 0.0],
            heading_deg: 0.0,
            speed: 8.0,
            begin: 1.0,
            distance: 12.0,
        };
        let tr = r.track(0.0, 6.0, 30.0).unwrap();
        let mut prev = f32::NEG_INFINITY;
        for k in &tr.keys {
            assert!(k.pose.translation.x >= prev - 1e-6, "reversed at t={}", k.t);
            prev = k.pose.translation.x;
            assert!(k.pose.translation.x <= 8.0 + 12.0 + 1e-4);
        }
        assert!((prev - 20.0).abs() < 1e-4);
    }

    #[test]
    fn deltas_accumulate_and_heading_follows_velocity() {
        let r = TrajectoryRule::Deltas {
            start: [1.0, 0.0, 1.0],
            deltas: vec![[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]],
        };
        let tr = r.track(0.0, 1.0, 10.0).unwrap();
        assert_eq!(tr.keys.len(), 4);
        assert_eq!(tr.keys[3].pose.translation, Vec3::new(2.0, 0.0, 2.0));
        assert!((forward(tr.keys[1].pose.rotation) - Vec3::Z).length() < 1e-6);
        // At rest the last heading is kept.
        assert!((forward(tr.keys[3].pose.rotation) - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn invalid_rules_are_errors() {
        let bad = TrajectoryRule::Turn {
            start: [0.0; 3],
            heading_deg: 0.0,
            speed: 1.0,
            radius: 0.0,
            angle_deg: 90.0,
            begin: 0.0,
        };
        assert!(bad.track(0.0, 1.0, 10.0).unwrap_err().0.contains("radius"));
        let json = r#"{"kind": "teleport", "start": [0,0,0]}"#;
        assert!(serde_json::from_str::<TrajectoryRule>(json).is_err());
        let nan = TrajectoryRule::Deltas {
            start: [0.0; 3],
            deltas: vec![[f32::NAN, 0.0, 0.0]],
        };
        assert!(nan.track(0.0, 1.0, 10.0).unwrap_err().0.contains("delta 0"));
    }
}
