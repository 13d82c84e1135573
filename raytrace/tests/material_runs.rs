//! `MaterialRuns` (each triangle's material, stored as runs) against the per-triangle list it
//! replaces, the reference: every lookup and the iteration agree, for one material, many short
//! runs, and materials that come back after other runs.

use splatbridge_raytrace::model::MaterialRuns;

fn check(per_triangle: &[u32]) {
    let runs = MaterialRuns::from(per_triangle.to_vec());
    assert_eq!(runs.len(), per_triangle.len());
    for (t, &m) in per_triangle.iter().enumerate() {
        assert_eq!(runs.get(t), m, "triangle {t} of {per_triangle:?}");
    }
    assert_eq!(runs.iter().collect::<Vec<_>>(), per_triangle);
    // Built by runs, as the loader does, it is the same value.
    let mut by_runs = MaterialRuns::default();
    let mut i = 0;
    while i < per_triangle.len() {
        let j = (i..per_triangle.len())
            .find(|&j| per_triangle[j] != per_triangle[i])
            .unwrap_or(per_triangle.len());
        by_runs.extend_with(j - i, per_triangle[i]);
        by_runs.extend_with(0, 99);
        i = j;
    }
    assert_eq!(by_runs, runs);
}

#[test]
fn material_runs_agree_with_the_per_triangle_list() {
    check(&[]);
    check(&[3; 1000]);
    check(&[0, 1, 1, 2, 2, 2, 0, 0, 5, 1]);
    // A pseudo-random sequence with long and single-triangle runs.
    let mut x = 12345u32;
    let v: Vec<u32> = (0..5000)
        .map(|_| {
            x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (x >> 16) % 4 / 3 + (x >> 20) % 2
        })
        .collect();
    check(&v);
}
