//! The one chunked mesher (`chunked::ChunkedMesh`) for both mesh sources, over clouds of
//! several chunks: the streamed vertices, the index buffer built from the per-item patterns
//! (prefix sums per chunk, no geometry) and the bounds pass all agree with the slow reference,
//! the whole mesh generated in one sink with its indices offset by hand.

use splatbridge_convert::chunked::CHUNK;
use splatbridge_convert::mesh::VertexSink;
use splatbridge_convert::surfels::{split_scene, SurfelMesher, SurfelOptions};
use splatbridge_convert::{shape_for, ChunkedMesh, ConvertOptions, MeshSoup, Mesher, Profile};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::fixtures::{street_with, StreetParams};

/// The reference: every item emitted into one soup (indices relative to its start).
fn whole<M: ChunkedMesh>(m: &M) -> MeshSoup {
    let mut soup = MeshSoup::default();
    let mut scratch = M::Scratch::default();
    m.emit_range(0..m.items(), &mut soup, &mut scratch);
    if !m.has_uv() {
        soup.uvs.clear();
    }
    soup
}

fn check<M: ChunkedMesh>(m: &M, what: &str) {
    assert!(m.chunk_count() >= 2, "{what}: a test of several chunks");
    let want = whole(m);
    assert!(want.vertex_count() > 0, "{what}");

    // Vertices streamed chunk by chunk, in order, each chunk's indices relative to it.
    let mut streamed = MeshSoup::default();
    let mut planned = Vec::new();
    m.map_chunks::<_, ()>(
        |c| c,
        |c| {
            planned.push(c.vertex_count());
            streamed.append(&c);
            Ok(())
        },
    )
    .unwrap();
    assert_eq!(streamed, want, "{what}: streamed chunks");
    let per_chunk: Vec<usize> = (0..m.chunk_count()).map(|c| m.chunk_vertices(c)).collect();
    assert_eq!(
        planned, per_chunk,
        "{what}: chunk sizes from the classification"
    );
    assert_eq!(
        m.build(),
        want,
        "{what}: the in-memory mesh is the streamed one"
    );

    // The index buffer without geometry, with a base added.
    let base = 7u32;
    let mut idx = Vec::new();
    m.map_index_chunks::<Vec<u32>, ()>(
        base,
        |c| c.to_vec(),
        |c| {
            idx.extend(c);
            Ok(())
        },
    )
    .unwrap();
    let want_idx: Vec<u32> = want.indices.iter().map(|i| i + base).collect();
    assert_eq!(idx, want_idx, "{what}: index chunks");

    // Exact bounds of the generated positions.
    let (lo, hi) = m.bounds().expect("non-empty");
    for a in 0..3 {
        let v = want.positions.iter().map(|p| p[a]);
        assert_eq!(lo[a], v.clone().fold(f32::INFINITY, f32::min), "{what}");
        assert_eq!(hi[a], v.fold(f32::NEG_INFINITY, f32::max), "{what}");
    }
}

/// A sink that only counts, to show `FULL = false` sinks see the same vertices.
#[derive(Default)]
struct Count(u32);

impl VertexSink for Count {
    const FULL: bool = false;
    fn vertex(&mut self, _: glam::Vec3, _: [f32; 3], _: [f32; 4], _: [f32; 2], _: u32) -> u32 {
        self.0 += 1;
        self.0 - 1
    }
    fn triangle(&mut self, _: [u32; 3]) {}
}

#[test]
fn gaussian_meshes_stream_like_the_whole_mesh() {
    // 2.5 chunks of Gaussians.
    let scene = street_with(&StreetParams::new(5, CHUNK * 5 / 2));
    let cloud = &scene.static_gaussians;
    for profile in [Profile::MeshSplats, Profile::Rings, Profile::Texture] {
        let opts = ConvertOptions {
            profile,
            segments: Some(4),
            rings: 1,
            coplanar_offset: true,
            ..Default::default()
        };
        let shape = shape_for(&opts);
        let m = Mesher::new(cloud, &shape, &opts, "static", 3);
        check(&m, profile.name());
        let mut n = Count::default();
        m.emit_range(0..m.items(), &mut n, &mut Default::default());
        assert_eq!(n.0 as u64, m.counts.vertices, "{}", profile.name());
    }
}

#[test]
fn surfel_meshes_stream_like_the_whole_mesh() {
    let cloud = street_with(&StreetParams::new(6, CHUNK * 4)).static_gaussians;
    let scene = DynamicScene::from_static(cloud);
    let so = SurfelOptions {
        // Low thresholds so that more than a chunk of Gaussians become surfels.
        min_opacity: 0.05,
        max_flatness: 1.0,
        segments: 6,
        guarded: false,
    };
    let split = split_scene(&scene, None, &so);
    let part = &split.parts[0];
    let m = SurfelMesher::new(
        part,
        &so,
        &ConvertOptions::default(),
        scene.static_gaussians.len() as u64,
    );
    check(&m, "surfels");
}
