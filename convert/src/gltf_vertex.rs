//! The interleaved vertex and index bytes of the glTF writer ([`crate::gltf_writer`]): one
//! vertex is POSITION f32×3, NORMAL f32×3 unless left out, COLOR_0 normalized u16×4,
//! `_GAUSSIAN_ID` f32 and TEXCOORD_0 f32×2 when asked, little-endian, 4-byte aligned.

/// Byte layout of one interleaved vertex.
#[derive(Clone, Copy, Debug)]
pub struct VertexLayout {
    pub ids: bool,
    pub uv: bool,
    pub normals: bool,
}

impl VertexLayout {
    pub fn stride(self) -> usize {
        self.id_offset() + if self.ids { 4 } else { 0 } + if self.uv { 8 } else { 0 }
    }
    pub(crate) fn color_offset(self) -> usize {
        if self.normals {
            24
        } else {
            12
        }
    }
    pub(crate) fn id_offset(self) -> usize {
        self.color_offset() + 8
    }
    pub(crate) fn uv_offset(self) -> usize {
        self.id_offset() + if self.ids { 4 } else { 0 }
    }
}

/// Encode a chunk's vertices interleaved.
pub fn vertex_bytes(s: &crate::MeshSoup, l: VertexLayout) -> Vec<u8> {
    let mut b = Vec::with_capacity(s.vertex_count() * l.stride());
    for v in 0..s.vertex_count() {
        let normal: &[f32] = if l.normals { &s.normals[v] } else { &[] };
        for x in s.positions[v].iter().chain(normal) {
            b.extend_from_slice(&x.to_le_bytes());
        }
        for c in s.colors[v] {
            b.extend_from_slice(&((c.clamp(0.0, 1.0) * 65535.0).round() as u16).to_le_bytes());
        }
        if l.ids {
            b.extend_from_slice(&(s.gaussian_ids[v] as f32).to_le_bytes());
        }
        if l.uv {
            for x in s.uvs[v] {
                b.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    b
}

/// A sink encoding vertices straight into the interleaved layout (no intermediate soup).
pub struct Interleaved {
    pub bytes: Vec<u8>,
    layout: VertexLayout,
    n: u32,
}

impl Interleaved {
    pub fn new(vertices: usize, layout: VertexLayout) -> Self {
        Interleaved {
            bytes: Vec::with_capacity(vertices * layout.stride()),
            layout,
            n: 0,
        }
    }
}

impl crate::mesh::VertexSink for Interleaved {
    const FULL: bool = true;
    #[inline]
    fn vertex(
        &mut self,
        p: glam::Vec3,
        normal: [f32; 3],
        rgba: [f32; 4],
        uv: [f32; 2],
        id: u32,
    ) -> u32 {
        let mut v = [0u8; 44];
        let mut put = |o: usize, b: [u8; 4]| v[o..o + 4].copy_from_slice(&b);
        let normal: &[f32] = if self.layout.normals { &normal } else { &[] };
        for (k, x) in p.to_array().iter().chain(normal).enumerate() {
            put(4 * k, x.to_le_bytes());
        }
        let q = |c: f32| ((c.clamp(0.0, 1.0) * 65535.0).round() as u16).to_le_bytes();
        let (c0, c1, c2, c3) = (q(rgba[0]), q(rgba[1]), q(rgba[2]), q(rgba[3]));
        let co = self.layout.color_offset();
        v[co..co + 8].copy_from_slice(&[c0[0], c0[1], c1[0], c1[1], c2[0], c2[1], c3[0], c3[1]]);
        let mut o = co + 8;
        if self.layout.ids {
            v[o..o + 4].copy_from_slice(&(id as f32).to_le_bytes());
            o += 4;
        }
        if self.layout.uv {
            v[o..o + 4].copy_from_slice(&uv[0].to_le_bytes());
            v[o + 4..o + 8].copy_from_slice(&uv[1].to_le_bytes());
        }
        self.bytes.extend_from_slice(&v[..self.layout.stride()]);
        self.n += 1;
        self.n - 1
    }
    #[inline]
    fn triangle(&mut self, _: [u32; 3]) {}
}

pub(crate) fn index_bytes(idx: &[u32]) -> Vec<u8> {
    let mut b = Vec::with_capacity(idx.len() * 4);
    for i in idx {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}
