//! The eight-lane kernels ([`super`]) against the scalar code they replace, lane by lane and
//! bit for bit: the rectangle and ellipse walk against `tiles`' scalar tests, `Chunk::q`
//! against [`PixelSplat::q`], and [`colors_from_basis`] against [`color_from_basis`]; on
//! random records with edge values (records that cannot hold the response, zero and negative
//! determinants, pixels on the rectangles' edges), and lists whose length is not a multiple of
//! eight.

use glam::Vec3;
use splatbridge_scene::rng::Rng;
use splatbridge_scene::sh;

use super::super::camera::{LocalFootprint, PixelSplat};
use super::super::cull_tests::random_rotation_and_sh;
use super::super::tiles::{color_from_basis, Cells, Entry, CELL, TILE};
use super::{colors_from_basis, Chunk, Products, LANES};
use crate::screen_cells::split_cells;

/// A random entry and record; some records degenerate (zero rows, huge values, `ok` false),
/// some entries without an ellipse (`k = 0`, `a_max = ∞`).
fn random(r: &mut Rng, p: u32) -> (Entry, PixelSplat) {
    let v3 = |r: &mut Rng, s: f32| {
        [
            r.range(-s, s) * r.range(0.0, 1.0),
            r.range(-s, s),
            r.range(-s, s),
        ]
    };
    let scale = if p.is_multiple_of(7) { 1e18 } else { 40.0 };
    let mut px = PixelSplat {
        mu: [r.range(-30.0, 30.0), r.range(-30.0, 30.0)],
        p0: v3(r, scale),
        p1: v3(r, scale),
        w: v3(r, 0.05),
        r2: r.range(0.5, 11.0),
        opacity: r.range(0.0, 1.0),
        ok: !p.is_multiple_of(11),
    };
    if p.is_multiple_of(13) {
        // b0 = b1 = 0 at every pixel: the determinant is s² alone.
        px.p0 = [0.0; 3];
        px.p1 = [0.0; 3];
        px.w = [0.0; 3];
    }
    if p.is_multiple_of(17) {
        px.p0 = [f32::MAX, 0.0, -f32::MAX];
    }
    let (u0, v0) = (r.range(-40.0, 40.0), r.range(-40.0, 40.0));
    let mut e = Entry {
        rect: [u0, v0, u0 + r.range(-1.0, 30.0), v0 + r.range(0.0, 30.0)],
        mu: px.mu,
        k: [r.range(0.0, 0.2), r.range(-0.05, 0.05), r.range(0.0, 0.2)],
        amax: r.range(0.0, 20.0),
        z: r.range(0.1, 10.0),
        p,
    };
    if p.is_multiple_of(5) {
        (e.k, e.amax) = ([0.0; 3], f32::INFINITY);
    }
    (e, px)
}

fn footprint(u: f32, v: f32, s: f32) -> LocalFootprint {
    LocalFootprint {
        forward: Vec3::Z,
        e1: Vec3::X,
        e2: Vec3::Y,
        cov: [0.0; 3],
        det: 0.0,
        pixel: (u, v),
        centred: (u, v),
        s,
        s2: s * s,
    }
}

/// The walk's tests and `q`, lane by lane, at random pixels and at the rectangles' corners.
#[test]
fn lanes_are_the_scalar_tests() {
    let mut r = Rng::new(41);
    let mut passed = 0;
    let mut q_some = 0;
    for n in [1usize, 7, 8, 9, 23, 64] {
        let items: Vec<(Entry, PixelSplat)> = (0..n as u32).map(|p| random(&mut r, p)).collect();
        let list: Vec<Entry> = items.iter().map(|x| x.0).collect();
        let mut chunks = Vec::new();
        Chunk::pack(&list, |p| items[p].1, &mut chunks);
        assert_eq!(chunks.len(), n.div_ceil(LANES));
        let corners = list
            .iter()
            .flat_map(|e| [(e.rect[0], e.rect[1]), (e.rect[2], e.rect[3])]);
        let randoms: Vec<(f32, f32)> = (0..200)
            .map(|_| (r.range(-45.0, 75.0), r.range(-45.0, 75.0)))
            .collect();
        for (u, v) in corners.chain(randoms) {
            let (cu, cv) = (u - 3.0, v + 1.5);
            let fp = footprint(cu, cv, 0.3);
            for (c, chunk) in chunks.iter().enumerate() {
                let mask = chunk.pass(u, v, cu, cv);
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: AVX2 is present.
                    let avx2 = unsafe { chunk.pass_avx2(u, v, cu, cv) };
                    assert_eq!(avx2, mask, "the AVX2 pass at ({u}, {v})");
                }
                let (q, ok) = chunk.q(fp.centred, fp.s, fp.s2);
                for l in 0..LANES {
                    let i = c * LANES + l;
                    let bit = mask >> l & 1 == 1;
                    let Some((e, px)) = items.get(i) else {
                        assert!(!bit, "a padding lane passed");
                        continue;
                    };
                    // The scalar walk's tests (`tiles`, before the lanes).
                    let inside =
                        u >= e.rect[0] && u <= e.rect[2] && v >= e.rect[1] && v <= e.rect[3];
                    let (x0, x1) = (e.mu[0] - cu, e.mu[1] - cv);
                    let ell =
                        e.k[0] * x0 * x0 + 2.0 * e.k[1] * x0 * x1 + e.k[2] * x1 * x1 <= e.amax;
                    assert_eq!(bit, inside && ell, "lane {i} at ({u}, {v})");
                    passed += bit as usize;
                    assert_eq!((chunk.z[l], chunk.p[l]), (e.z, e.p));
                    assert_eq!(chunk.ok[l], px.ok);
                    let lane = (ok >> l & 1 == 1).then_some(q[l]);
                    let scalar = px.q(&fp);
                    assert_eq!(
                        lane.map(f32::to_bits),
                        scalar.map(f32::to_bits),
                        "q of lane {i}"
                    );
                    q_some += scalar.is_some() as usize;
                }
            }
        }
    }
    // Both outcomes occur (the tests can fail either way).
    assert!(passed > 100, "{passed}");
    assert!(q_some > 100, "{q_some}");
}

/// The colours of up to eight hits together are `color_from_basis`'s, bit for bit, at every
/// degree and group size.
#[test]
fn colors_together_are_color_from_basis() {
    let mut r = Rng::new(43);
    // Reused across calls, as a tile reuses it across rays.
    let mut products = Products::default();
    for degree in 0..=3u8 {
        let k = (degree as usize + 1).pow(2);
        for n in 1..=LANES {
            for _ in 0..200 {
                let d = Vec3::new(r.normal(), r.normal(), r.normal()).normalize();
                let b = sh::basis(degree, d);
                let sets: Vec<Vec<Vec3>> = (0..n)
                    .map(|_| {
                        let (_, base) = random_rotation_and_sh(&mut r);
                        (0..k).map(|j| base[j % 4] * (1.0 + j as f32)).collect()
                    })
                    .collect();
                let refs: Vec<&[Vec3]> = sets.iter().map(|s| s.as_slice()).collect();
                let mut out = vec![Vec3::ONE];
                colors_from_basis(&refs, &b, &mut products, &mut out);
                assert_eq!(out.len(), n + 1, "appends one colour a hit");
                for (s, c) in sets.iter().zip(&out[1..]) {
                    let one = color_from_basis(s, &b);
                    assert_eq!(
                        c.to_array().map(f32::to_bits),
                        one.to_array().map(f32::to_bits)
                    );
                }
            }
        }
    }
}

/// A tile's chunked cells are `split_cells`' lists packed eight at a time, cell by cell, for
/// tiles whose rectangles reach past every side, and with and without records.
#[test]
fn cells_are_split_cells_packed() {
    let mut r = Rng::new(47);
    for (n, tile) in [
        (0usize, (0u32, 0u32)),
        (5, (1, 1)),
        (40, (1, 2)),
        (300, (2, 1)),
    ] {
        let items: Vec<(Entry, PixelSplat)> = (0..n as u32).map(|p| random(&mut r, p)).collect();
        let list: Vec<Entry> = items.iter().map(|x| x.0).collect();
        let records: Vec<PixelSplat> = items.iter().map(|x| x.1).collect();
        let lists = split_cells(&list, |e| e.rect, tile, TILE, CELL);
        for with_records in [true, false] {
            let cells = Cells::build(&list, with_records.then_some(records.as_slice()), tile);
            let mut filled = 0;
            for (c, cell_list) in lists.iter().enumerate() {
                let m = (TILE / CELL) as usize;
                let (i, j) = (
                    tile.0 * TILE + (c % m) as u32 * CELL + 1,
                    tile.1 * TILE + (c / m) as u32 * CELL + 2,
                );
                let mut expected = Vec::new();
                let record = |p: usize| {
                    if with_records {
                        records[p]
                    } else {
                        PixelSplat::default()
                    }
                };
                Chunk::pack(cell_list, record, &mut expected);
                assert_eq!(
                    cells.of(i, j),
                    expected.as_slice(),
                    "cell {c} of {n} entries"
                );
                filled += cell_list.len();
            }
            assert!(filled >= n, "{filled} of {n}: every entry is in a cell");
        }
    }
}
