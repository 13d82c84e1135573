//! Agreement between two labelings of the same Gaussians: the adjusted Rand index (Hubert &
//! Arabie, "Comparing partitions", J. Classification 2, 1985), the chance-corrected share of
//! pairs both labelings put together or apart. 1 is identical groupings (whatever the label
//! names), about 0 is chance.

use std::collections::HashMap;

fn pairs(n: u64) -> f64 {
    (n as f64) * (n as f64 - 1.0) / 2.0
}

/// The adjusted Rand index of labelings `a` and `b` (same length), from their contingency
/// table. Two labelings that each put everything in one group (or both have at most one
/// Gaussian) agree perfectly: 1.
pub fn adjusted_rand_index(a: &[u32], b: &[u32]) -> f64 {
    assert_eq!(a.len(), b.len(), "labelings of different lengths");
    let mut table: HashMap<(u32, u32), u64> = HashMap::new();
    let mut rows: HashMap<u32, u64> = HashMap::new();
    let mut cols: HashMap<u32, u64> = HashMap::new();
    for (&x, &y) in a.iter().zip(b) {
        *table.entry((x, y)).or_default() += 1;
        *rows.entry(x).or_default() += 1;
        *cols.entry(y).or_default() += 1;
    }
    let index: f64 = table.values().map(|&n| pairs(n)).sum();
    let sa: f64 = rows.values().map(|&n| pairs(n)).sum();
    let sb: f64 = cols.values().map(|&n| pairs(n)).sum();
    ari_from(index, sa, sb, pairs(a.len() as u64))
}

fn ari_from(index: f64, sa: f64, sb: f64, total: f64) -> f64 {
    if total == 0.0 {
        return 1.0;
    }
    let expected = sa * sb / total;
    let max = 0.5 * (sa + sb);
    if max == expected {
        // Both labelings trivial (all together or all apart): they agree exactly when equal.
        return if index == max { 1.0 } else { 0.0 };
    }
    (index - expected) / (max - expected)
}

#[cfg(test)]
mod tests {
    use super::*;
    use splatbridge_scene::rng::Rng;

    /// The slow reference: count the pairs one by one.
    fn ari_by_pairs(a: &[u32], b: &[u32]) -> f64 {
        let (mut index, mut sa, mut sb) = (0.0, 0.0, 0.0);
        for i in 0..a.len() {
            for j in i + 1..a.len() {
                let (x, y) = (a[i] == a[j], b[i] == b[j]);
                index += (x && y) as u8 as f64;
                sa += x as u8 as f64;
                sb += y as u8 as f64;
            }
        }
        ari_from(index, sa, sb, pairs(a.len() as u64))
    }

    #[test]
    fn matches_pair_counting() {
        let mut rng = Rng::new(5);
        for case in 0..40 {
            let n = 1 + rng.below(200) as usize;
            let ka = 1 + rng.below(6);
            let kb = 1 + rng.below(6);
            let a: Vec<u32> = (0..n).map(|_| rng.below(ka) as u32).collect();
            // Half the cases: b is a with a few labels changed, so values near 1 are tested.
            let b: Vec<u32> = if case % 2 == 0 {
                a.iter()
                    .map(|&x| {
                        if rng.f32() < 0.05 {
                            rng.below(kb) as u32
                        } else {
                            x + 7
                        }
                    })
                    .collect()
            } else {
                (0..n).map(|_| rng.below(kb) as u32).collect()
            };
            let fast = adjusted_rand_index(&a, &b);
            let slow = ari_by_pairs(&a, &b);
            // Same sums in another order: f64 rounding only.
            assert!((fast - slow).abs() < 1e-9, "{fast} vs {slow}");
        }
    }

    #[test]
    fn renamed_labels_agree_and_known_value() {
        assert_eq!(adjusted_rand_index(&[0, 0, 1, 1], &[5, 5, 2, 2]), 1.0);
        // Hubert–Arabie by hand: a = {0,0,1,1}, b = {0,0,0,1}: index 1, sa 2, sb 3, total 6,
        // expected 1, max 2.5: ARI 0.
        assert_eq!(adjusted_rand_index(&[0, 0, 1, 1], &[0, 0, 0, 1]), 0.0);
        assert_eq!(adjusted_rand_index(&[], &[]), 1.0);
        assert_eq!(adjusted_rand_index(&[1, 1, 1], &[2, 2, 2]), 1.0);
    }
}
