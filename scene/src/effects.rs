//! Declared effects: the manifest's `effects` object, typed and validated. Nothing is simulated
//! unless it is declared here; renderers and reports read these to decide what runs and to say
//! what ran (see [`EffectCounters`]).
//!
//! Units are the scene's own (3DGS captures are rarely metric); directions are world-space and
//! the world is y-down unless a scene says otherwise.

use serde::{Deserialize, Serialize};

/// All effects a scene may declare. Unknown names are errors (`deny_unknown_fields`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weather: Option<Weather>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_blur: Option<MotionBlur>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shadows: Option<Shadows>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lidar: Option<Lidar>,
}

/// Rain or snow particles, regenerated per frame from `seed` with parametric trajectories.
/// Most weather particles a scene may declare. Every renderer holds the particles as a
/// Gaussian cloud plus per-Gaussian projection or BVH state, about 0.5 KiB each at the peak (a
/// trace of 10 million particles at 64×48 needed 5 GB); one million keeps that near 500 MB
/// and is far denser than any visible rain.
pub const MAX_WEATHER_COUNT: u32 = 1_000_000;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Weather {
    pub kind: WeatherKind,
    /// Particles alive at any time (they wrap around the volume, so the count is constant);
    /// 1..=[`MAX_WEATHER_COUNT`].
    pub count: u32,
    #[serde(default)]
    pub seed: u64,
    /// Fall speed in scene units per second along world "down" (+y).
    pub fall_speed: f32,
    /// Wind velocity added to every particle, scene units per second.
    #[serde(default)]
    pub wind: [f32; 3],
    /// Amplitude of the sinusoidal sideways drift, scene units.
    #[serde(default)]
    pub turbulence: f32,
    /// Particle size (the cross-section's standard deviation), scene units.
    pub size: f32,
    /// Where particles live.
    #[serde(default)]
    pub volume: WeatherVolume,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WeatherKind {
    Rain,
    Snow,
}

/// The spawn volume: the scene's robust bounds, a box around a camera, or an explicit box.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum WeatherVolume {
    #[default]
    Scene,
    Camera {
        index: usize,
        half_extent: [f32; 3],
    },
    Box {
        min: [f32; 3],
        max: [f32; 3],
    },
}

/// A shutter interval `[t, t + shutter]`; moving objects are sampled `samples` times over it,
/// static content once.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionBlur {
    pub shutter: f64,
    #[serde(default = "default_blur_samples")]
    pub samples: u32,
}

fn default_blur_samples() -> u32 {
    8
}

/// Sun shadows: the ray tracer casts a shadow ray per shaded hit towards `sun_direction` and
/// darkens by `strength · (1 − transmittance)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shadows {
    /// Direction towards the sun (normalised on use).
    pub sun_direction: [f32; 3],
    /// 0 = no darkening, 1 = fully dark where the sun is fully blocked.
    pub strength: f32,
}

/// A spinning LiDAR ray-cast through the scene each frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Lidar {
    pub channels: u32,
    /// Lowest and highest elevation angle, degrees (positive = up).
    pub vertical_fov_deg: [f32; 2],
    /// Revolutions per second.
    pub rotation_hz: f32,
    /// Azimuth samples per revolution.
    pub azimuth_steps: u32,
    /// Maximum range, scene units.
    pub range: f32,
    /// Where the sensor is: a fixed pose, or attached to one of the scene's cameras.
    pub mount: LidarMount,
    /// A return needs at least this opacity accumulated along the ray (default 0.5).
    #[serde(default = "default_lidar_threshold")]
    pub hit_threshold: f32,
}

fn default_lidar_threshold() -> f32 {
    0.5
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum LidarMount {
    /// Sensor origin and rotation (w, x, y, z); the sensor spins about its local −y (up).
    Pose {
        position: [f32; 3],
        rotation: [f32; 4],
    },
    /// Rigidly at camera `index` of the scene's cameras.
    Camera { index: usize },
}

/// What an effect run did: every report carries these, zeros when nothing was declared.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EffectCounters {
    pub particles: u64,
    pub shadow_rays: u64,
    pub lidar_points: u64,
    pub lidar_rays: u64,
    /// Time samples beyond the one every frame needs (motion blur).
    pub extra_time_samples: u64,
    pub milliseconds: f64,
    /// Names of the effects that ran.
    pub simulated: Vec<String>,
    /// Declared effects a renderer does not simulate (said in its report).
    pub not_simulated: Vec<String>,
}

impl EffectCounters {
    /// Add another frame's (or sample's) counters: counts and time summed, names merged in
    /// first-seen order.
    pub fn add(&mut self, other: &EffectCounters) {
        self.particles += other.particles;
        self.shadow_rays += other.shadow_rays;
        self.lidar_points += other.lidar_points;
        self.lidar_rays += other.lidar_rays;
        self.extra_time_samples += other.extra_time_samples;
        self.milliseconds += other.milliseconds;
        for (mine, theirs) in [
            (&mut self.simulated, &other.simulated),
            (&mut self.not_simulated, &other.not_simulated),
        ] {
            for n in theirs {
                if !mine.contains(n) {
                    mine.push(n.clone());
                }
            }
        }
    }

    /// One line for a run's stdout summary: what ran, its counts and time, and what a renderer
    /// left out.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "effects: {} | particles {}, extra time samples {}, shadow rays {}, LiDAR rays {} → points {}, {:.1} ms",
            if self.simulated.is_empty() {
                "none".to_string()
            } else {
                self.simulated.join(", ")
            },
            self.particles,
            self.extra_time_samples,
            self.shadow_rays,
            self.lidar_rays,
            self.lidar_points,
            self.milliseconds
        );
        if !self.not_simulated.is_empty() {
            s.push_str(&format!(
                " | declared but not simulated here: {}",
                self.not_simulated.join(", ")
            ));
        }
        s
    }

    /// True when no effect did any work (what an undeclared effect must show).
    pub fn is_zero(&self) -> bool {
        self.particles == 0
            && self.shadow_rays == 0
            && self.lidar_points == 0
            && self.lidar_rays == 0
            && self.extra_time_samples == 0
            && self.simulated.is_empty()
    }
}

impl Effects {
    /// Parse and validate the manifest's `effects` object. Errors name the effect and field.
    pub fn from_json(value: &serde_json::Map<String, serde_json::Value>) -> Result<Self, String> {
        let e: Effects =
            serde_json::from_value(serde_json::Value::Object(value.clone())).map_err(|e| {
                format!("effects: {e} (known effects: weather, motion_blur, shadows, lidar)")
            })?;
        e.validate()?;
        Ok(e)
    }

    pub fn is_empty(&self) -> bool {
        self.weather.is_none()
            && self.motion_blur.is_none()
            && self.shadows.is_none()
            && self.lidar.is_none()
    }

    /// Names of the declared effects, in a fixed order.
    pub fn names(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        if self.weather.is_some() {
            v.push("weather");
        }
        if self.motion_blur.is_some() {
            v.push("motion_blur");
        }
        if self.shadows.is_some() {
            v.push("shadows");
        }
        if self.lidar.is_some() {
            v.push("lidar");
        }
        v
    }

    pub fn validate(&self) -> Result<(), String> {
        let fin = |v: &[f32]| v.iter().all(|x| x.is_finite());
        if let Some(w) = &self.weather {
            if w.count == 0 || w.count > MAX_WEATHER_COUNT {
                return Err(format!(
                    "effects.weather.count: {} is outside 1..={MAX_WEATHER_COUNT}",
                    w.count
                ));
            }
            if !(w.fall_speed.is_finite() && w.fall_speed >= 0.0) {
                return Err("effects.weather.fall_speed must be finite and not negative".into());
            }
            if !(w.size.is_finite() && w.size > 0.0) {
                return Err("effects.weather.size must be positive".into());
            }
            if !fin(&w.wind) || !(w.turbulence.is_finite() && w.turbulence >= 0.0) {
                return Err(
                    "effects.weather: wind and turbulence must be finite (turbulence ≥ 0)".into(),
                );
            }
            match &w.volume {
                WeatherVolume::Box { min, max } => {
                    if !fin(min) || !fin(max) || (0..3).any(|k| max[k] <= min[k]) {
                        return Err(
                            "effects.weather.volume.box: min must be below max on every axis"
                                .into(),
                        );
                    }
                }
                WeatherVolume::Camera { half_extent, .. } => {
                    if !fin(half_extent) || half_extent.iter().any(|&h| h <= 0.0) {
                        return Err(
                            "effects.weather.volume.camera.half_extent must be positive".into()
                        );
                    }
                }
                WeatherVolume::Scene => {}
            }
        }
        if let Some(m) = &self.motion_blur {
            if !(m.shutter.is_finite() && m.shutter > 0.0) {
                return Err(format!(
                    "effects.motion_blur.shutter: {} must be positive",
                    m.shutter
                ));
            }
            if m.samples < 2 || m.samples > 256 {
                return Err(format!(
                    "effects.motion_blur.samples: {} is outside 2..=256",
                    m.samples
                ));
            }
        }
        if let Some(s) = &self.shadows {
            let d = glam::Vec3::from(s.sun_direction);
            if !d.is_finite() || d.length() < 1e-6 {
                return Err(
                    "effects.shadows.sun_direction must be a finite non-zero vector".into(),
                );
            }
            if !(0.0..=1.0).contains(&s.strength) {
                return Err(format!(
                    "effects.shadows.strength: {} is outside [0, 1]",
                    s.strength
                ));
            }
        }
        if let Some(l) = &self.lidar {
            if l.channels == 0
                || l.channels > 1024
                || l.azimuth_steps == 0
                || l.azimuth_steps > 100_000
            {
                return Err(
                    "effects.lidar: channels must be 1..=1024 and azimuth_steps 1..=100000".into(),
                );
            }
            let [lo, hi] = l.vertical_fov_deg;
            if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= -90.0 && hi <= 90.0) {
                return Err(
                    "effects.lidar.vertical_fov_deg must be [low, high] within [-90, 90]".into(),
                );
            }
            if !(l.range.is_finite() && l.range > 0.0)
                || !(l.rotation_hz.is_finite() && l.rotation_hz > 0.0)
            {
                return Err("effects.lidar: range and rotation_hz must be positive".into());
            }
            if !(0.0..=1.0).contains(&l.hit_threshold) || l.hit_threshold == 0.0 {
                return Err("effects.lidar.hit_threshold must be in (0, 1]".into());
            }
            if let LidarMount::Pose { position, rotation } = &l.mount {
                if !fin(position) || !fin(rotation) || rotation.iter().all(|&x| x == 0.0) {
                    return Err(
                        "effects.lidar.mount.pose: position and a non-zero rotation are required"
                            .into(),
                    );
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Effects, String> {
        let v: serde_json::Value = serde_json::from_str(s).unwrap();
        Effects::from_json(v.as_object().unwrap())
    }

    #[test]
    fn empty_effects_are_empty() {
        let e = parse("{}").unwrap();
        assert!(e.is_empty());
        assert!(e.names().is_empty());
    }

    #[test]
    fn counters_add_and_summarise() {
        let mut a = EffectCounters {
            particles: 10,
            simulated: vec!["weather".into()],
            milliseconds: 1.5,
            ..Default::default()
        };
        assert!(!a.is_zero());
        assert!(EffectCounters::default().is_zero());
        let b = EffectCounters {
            particles: 5,
            shadow_rays: 7,
            simulated: vec!["weather".into(), "shadows".into()],
            not_simulated: vec!["lidar".into()],
            milliseconds: 0.5,
            ..Default::default()
        };
        a.add(&b);
        assert_eq!((a.particles, a.shadow_rays, a.milliseconds), (15, 7, 2.0));
        assert_eq!(a.simulated, ["weather", "shadows"]);
        let s = a.summary();
        assert!(
            s.contains("weather, shadows") && s.contains("not simulated here: lidar"),
            "{s}"
        );
        assert!(EffectCounters::default()
            .summary()
            .starts_with("effects: none"));
    }

    #[test]
    fn unknown_effect_is_an_error() {
        let e = parse(r#"{"fog": {}}"#).unwrap_err();
        assert!(e.contains("fog"), "{e}");
    }

    #[test]
    fn every_effect_parses_and_validates() {
        let e = parse(
            r#"{"weather": {"kind": "rain", "count": 1000, "fall_speed": 8, "size": 0.01, "wind": [1,0,0]},
                "motion_blur": {"shutter": 0.02},
                "shadows": {"sun_direction": [0.3,-1,0.2], "strength": 0.6},
                "lidar": {"channels": 16, "vertical_fov_deg": [-15, 15], "rotation_hz": 10,
                          "azimuth_steps": 360, "range": 50, "mount": {"camera": {"index": 0}}}}"#,
        )
        .unwrap();
        assert_eq!(e.names(), ["weather", "motion_blur", "shadows", "lidar"]);
        assert_eq!(e.motion_blur.unwrap().samples, 8);
    }

    #[test]
    fn invalid_values_name_the_field() {
        assert!(
            parse(r#"{"shadows": {"sun_direction": [0,0,0], "strength": 0.5}}"#)
                .unwrap_err()
                .contains("sun_direction")
        );
        assert!(parse(r#"{"motion_blur": {"shutter": -1}}"#)
            .unwrap_err()
            .contains("shutter"));
        assert!(
            parse(r#"{"weather": {"kind": "hail", "count": 1, "fall_speed": 1, "size": 1}}"#)
                .is_err()
        );
    }
}
