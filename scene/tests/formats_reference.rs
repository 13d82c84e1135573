//! Decoding agrees with the reference decoder on the reference encoder's files, without npm:
//! `fixtures/formats/cut300.ply` (the first 300 Gaussians of `fourth_st.ply`, SH degree 3, cut
//! with `splatbridge convert --splats --first 300`) was encoded by `@playcanvas/splat-transform`
//! 3.7.0 (`cut300.spz`, SPZ version 4 via nianticlabs/spz's own code; `cut300.compressed.ply`)
//! and each decoded back by splat-transform to a float PLY (`*.st.ply`). See
//! `fixtures/formats/README.md`.
//!
//! splat-transform reads and writes SPZ data without the RUB ↔ RDF conversion nianticlabs/spz
//! specifies (and that `fourth_st.spz` → `fourth_st.ply` confirms, see formats_spz.rs): its
//! SPZ results differ from ours by exactly half a turn about x ([`flip_yz`]), which the SPZ
//! comparisons here undo and check.

mod formats_common;

use formats_common::{assert_same_decode, fixtures, max_err};
use splatbridge_scene::formats::spz::flip_yz;
use splatbridge_scene::formats::{detect, load_cloud, SplatFormat};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::GaussianCloud;

fn read(name: &str) -> GaussianCloud {
    load_cloud(&fixtures().join(name), &ReadOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .0
}

#[test]
fn spz_v4_from_splat_transform_decodes_like_the_reference() {
    let path = fixtures().join("cut300.spz");
    assert_eq!(detect(&path).unwrap(), SplatFormat::Spz { version: 4 });
    let ours = read("cut300.spz");
    let mut reference = read("cut300.spz.st.ply");
    assert_eq!(ours.sh_degree, 3);
    // Without the turn they disagree far beyond any quantisation step...
    assert!(max_err(&ours, &reference).pos > 0.01);
    // ...and with it they agree.
    flip_yz(&mut reference);
    let e = max_err(&ours, &reference);
    println!("cut300.spz, ours vs splat-transform: {e:?}");
    assert_same_decode(&e);
}

#[test]
fn spz_v4_is_within_quantisation_of_the_original() {
    let ours = read("cut300.spz");
    // splat-transform wrote cut300.ply's values into the stream unconverted.
    let mut original = read("cut300.ply");
    flip_yz(&mut original);
    let e = max_err(&ours, &original);
    println!("cut300.spz vs cut300.ply: {e:?}");
    // The quantisation bounds of formats_spz.rs (12 fraction bits, 1/16 log-scale steps,
    // smallest three, 8-bit opacity and colour, 16-step SH buckets).
    assert!(e.pos <= 1.23e-4, "{e:?}");
    assert!(e.log_scale <= 1.0 / 32.0 + 1e-6, "{e:?}");
    assert!(e.rot_angle <= 4.8e-3, "{e:?}");
    assert!(e.opacity <= 1.0 / 255.0 + 1e-6, "{e:?}");
    assert!(e.colour <= 3.7e-3, "{e:?}");
    assert!(e.sh_rest <= 8.5 / 128.0 + 1e-6, "{e:?}");
}

#[test]
fn compressed_ply_from_splat_transform_decodes_like_the_reference() {
    let path = fixtures().join("cut300.compressed.ply");
    assert_eq!(detect(&path).unwrap(), SplatFormat::CompressedPly);
    let ours = read("cut300.compressed.ply");
    let reference = read("cut300.compressed.st.ply");
    let e = max_err(&ours, &reference);
    println!("cut300.compressed.ply, ours vs splat-transform: {e:?}");
    // Same formulas (f32 here, f64 in JavaScript before the f32 store): rounding only.
    assert!(e.pos <= 1e-6, "{e:?}");
    assert!(e.log_scale <= 1e-5, "{e:?}");
    assert!(e.rot_angle <= 1e-3, "{e:?}");
    assert!(e.opacity <= 1e-5, "{e:?}");
    assert!(e.colour <= 1e-5, "{e:?}");
    assert!(e.sh_rest <= 1e-5, "{e:?}");
}
