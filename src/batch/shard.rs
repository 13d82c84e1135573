//! Shards: a deterministic partition of a run's work items, so N processes (a Slurm job array,
//! a Kubernetes Indexed Job, a CI matrix) each do their part and `splatbridge merge` joins the
//! parts into what one process writes.
//!
//! A work item is named by a [`WorkKey`] — (scene, time, camera, setting) — and shard `I` of `N`
//! owns it when `fnv1a64(key) mod N == I`. The hash is 64-bit FNV-1a (Fowler–Noll–Vo, offset
//! basis 0xcbf29ce484222325, prime 0x100000001b3) over the key's canonical bytes:
//!
//! ```text
//! scene ␀ time ␀ camera ␀ setting
//! ```
//!
//! where `time` is the time's IEEE-754 bits as 16 lower-case hex digits (so `0.5` and `0.50`
//! are one key and no float formatting is involved) and `␀` is a zero byte. It is not `std`'s
//! `DefaultHasher`, whose keys are randomised per process: every shard, on any machine and
//! build, must agree on who owns what. The same FNV-1a hashes scenes and options
//! ([`Fnv1a`]), which only need to be equal when the inputs are.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Largest shard count accepted: far above any batch array in practice, and small enough that
/// a merge's bookkeeping per shard stays trivial.
pub const MAX_SHARDS: u32 = 100_000;

/// Shard `index` of `count` (0-based: `0/4` … `3/4`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

#[derive(Debug, Error, PartialEq, Eq)]
pub enum ShardError {
    #[error("--shard '{0}': expected I/N with 0 ≤ I < N ≤ {MAX_SHARDS} (e.g. 0/4)")]
    Syntax(String),
}

impl FromStr for Shard {
    type Err = ShardError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || ShardError::Syntax(s.chars().take(64).collect());
        let (i, n) = s.trim().split_once('/').ok_or_else(bad)?;
        let digits =
            |t: &str| !t.is_empty() && t.len() <= 6 && t.bytes().all(|b| b.is_ascii_digit());
        if !digits(i) || !digits(n) {
            return Err(bad());
        }
        let index: u32 = i.parse().map_err(|_| bad())?;
        let count: u32 = n.parse().map_err(|_| bad())?;
        if count == 0 || count > MAX_SHARDS || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// The whole run as one shard.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Whether this shard does `key`'s work.
    pub fn owns(&self, key: &WorkKey) -> bool {
        key.hash() % u64::from(self.count) == u64::from(self.index)
    }
}

/// One unit of work: the scene (a name stable across shards, e.g. the input path as given),
/// the time, the camera (its name) and the setting (a renderer, a knob value; empty when the
/// item covers every setting).
#[derive(Clone, Debug, PartialEq)]
pub struct WorkKey {
    pub scene: String,
    pub time: f64,
    pub camera: String,
    pub setting: String,
}

impl WorkKey {
    /// The key's canonical bytes (see the module documentation).
    pub fn canonical(&self) -> Vec<u8> {
        let mut v = Vec::with_capacity(self.scene.len() + self.camera.len() + 40);
        v.extend_from_slice(self.scene.as_bytes());
        v.push(0);
        v.extend_from_slice(format!("{:016x}", self.time.to_bits()).as_bytes());
        v.push(0);
        v.extend_from_slice(self.camera.as_bytes());
        v.push(0);
        v.extend_from_slice(self.setting.as_bytes());
        v
    }

    /// 64-bit FNV-1a of the canonical bytes.
    pub fn hash(&self) -> u64 {
        let mut h = Fnv1a::new();
        h.write(&self.canonical());
        h.finish()
    }
}

/// 64-bit FNV-1a, streamed.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Self::new()
    }
}

impl Fnv1a {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    pub fn new() -> Self {
        Fnv1a(Self::OFFSET)
    }

    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(Self::PRIME);
        }
    }

    /// Each value's little-endian bytes, in order.
    pub fn write_f32s(&mut self, values: &[f32]) {
        for v in values {
            self.write(&v.to_le_bytes());
        }
    }

    pub fn finish(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_refuses() {
        assert_eq!("0/4".parse(), Ok(Shard { index: 0, count: 4 }));
        assert_eq!("3/4".parse(), Ok(Shard { index: 3, count: 4 }));
        for bad in [
            "4/4",
            "0/0",
            "1",
            "-1/4",
            "a/4",
            "1/4/2",
            "",
            "/",
            "1/1000000",
            "+1/4",
        ] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        assert_eq!(Shard { index: 2, count: 7 }.to_string(), "2/7");
    }

    /// Published FNV-1a 64 test vectors (the FNV reference page's `""`, `"a"`, `"foobar"`).
    #[test]
    fn fnv_vectors() {
        let h = |s: &str| {
            let mut f = Fnv1a::new();
            f.write(s.as_bytes());
            f.finish()
        };
        assert_eq!(h(""), 0xcbf29ce484222325);
        assert_eq!(h("a"), 0xaf63dc4c8601ec8c);
        assert_eq!(h("foobar"), 0x85944171f73967e8);
    }

    /// Every key is owned by exactly one shard, for several counts, and the split is not
    /// degenerate (each of 4 shards gets some of 400 keys).
    #[test]
    fn partition_is_exact() {
        let keys: Vec<WorkKey> = (0..400)
            .map(|i| WorkKey {
                scene: "s".into(),
                time: (i % 5) as f64 * 0.5,
                camera: format!("orbit_{}", i / 5),
                setting: String::new(),
            })
            .collect();
        for n in 1..=7u32 {
            let mut counts = vec![0usize; n as usize];
            for k in &keys {
                let owners: Vec<u32> = (0..n)
                    .filter(|&i| Shard { index: i, count: n }.owns(k))
                    .collect();
                assert_eq!(owners.len(), 1);
                counts[owners[0] as usize] += 1;
            }
            if n == 4 {
                assert!(counts.iter().all(|&c| c > 50), "{counts:?}");
            }
        }
    }

    /// The canonical form is pinned: a change would re-partition every user's running arrays.
    #[test]
    fn canonical_bytes_are_stable() {
        let k = WorkKey {
            scene: "a.ply".into(),
            time: 0.5,
            camera: "orbit_1".into(),
            setting: "x".into(),
        };
        assert_eq!(
            k.canonical(),
            b"a.ply\x003fe0000000000000\x00orbit_1\x00x".to_vec()
        );
    }
}
