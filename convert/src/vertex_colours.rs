//! Per-vertex RGBA that replaces the colours a profile derives from each Gaussian: what mesh
//! distillation (fitting the exported mesh to native splatting, as MeshSplats fine-tunes its
//! vertex colours) hands back to the writers, so a distilled export is written by the same
//! code as any other.
//!
//! It may also carry fitted vertex positions (distillation with `--distill-positions`), in
//! the frame the Gaussian's mesh is written in, which replace the profile's positions.
//!
//! Keyed by `_GAUSSIAN_ID` (the Gaussian's index in `composite` order) and by the vertex's
//! place in that Gaussian's template (the order [`crate::Mesher`] emits it), so the table does
//! not depend on the layout (chunks, windings) the writer arranges the Gaussians in.

/// Replacement colours, in the export's colour encoding (linear by default), per Gaussian.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexColours {
    /// Per `_GAUSSIAN_ID`: index of its first colour in `colours`, or `u32::MAX` to keep the
    /// profile's colours.
    start: Vec<u32>,
    /// Per `_GAUSSIAN_ID`: how many colours it has (the template's vertex count).
    count: Vec<u16>,
    colours: Vec<[f32; 4]>,
    /// Fitted positions parallel to `colours`, when positions were fitted.
    positions: Option<Vec<[f32; 3]>>,
}

impl VertexColours {
    /// An empty table for ids below `ids`.
    pub fn new(ids: usize) -> Self {
        VertexColours {
            start: vec![u32::MAX; ids],
            count: vec![0; ids],
            colours: Vec::new(),
            positions: None,
        }
    }

    /// An empty table for ids below `ids` that also carries positions ([`Self::set_positions`]).
    pub fn with_positions(ids: usize) -> Self {
        VertexColours {
            positions: Some(Vec::new()),
            ..Self::new(ids)
        }
    }

    /// Set Gaussian `id`'s colours and positions (one each per template vertex). Fails as
    /// [`Self::set`] does, when the table carries no positions, when the counts differ or a
    /// coordinate is not finite.
    pub fn set_positions(
        &mut self,
        id: u32,
        colours: &[[f32; 4]],
        positions: &[[f32; 3]],
    ) -> Result<(), String> {
        if colours.len() != positions.len() {
            return Err(format!(
                "vertex colours: Gaussian id {id} has {} colours and {} positions",
                colours.len(),
                positions.len()
            ));
        }
        if positions.iter().flatten().any(|x| !x.is_finite()) {
            return Err(format!(
                "vertex colours: Gaussian id {id} has a position that is not finite"
            ));
        }
        if self.positions.is_none() {
            return Err("vertex colours: this table carries no positions".into());
        }
        self.insert(id, colours)?;
        if let Some(p) = &mut self.positions {
            p.extend_from_slice(positions);
        }
        Ok(())
    }

    /// Set Gaussian `id`'s colours (its template's vertices, in emission order). Values are
    /// clamped to [0, 1], glTF's range for normalized colours. Fails when the id is out of
    /// range, already set, or the table would exceed u32 indices.
    pub fn set(&mut self, id: u32, colours: &[[f32; 4]]) -> Result<(), String> {
        if self.positions.is_some() {
            return Err("vertex colours: this table carries positions (set_positions)".into());
        }
        self.insert(id, colours)
    }

    fn insert(&mut self, id: u32, colours: &[[f32; 4]]) -> Result<(), String> {
        let i = id as usize;
        if i >= self.start.len() {
            return Err(format!("vertex colours: Gaussian id {id} is out of range"));
        }
        if self.start[i] != u32::MAX {
            return Err(format!("vertex colours: Gaussian id {id} is set twice"));
        }
        let (Ok(start), Ok(n)) = (
            u32::try_from(self.colours.len()),
            u16::try_from(colours.len()),
        ) else {
            return Err("vertex colours: table too large".into());
        };
        self.start[i] = start;
        self.count[i] = n;
        self.colours.extend(colours.iter().map(|c| {
            c.map(|x| {
                if x.is_finite() {
                    x.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
        }));
        Ok(())
    }

    /// Gaussian `id`'s colours, if the table has them.
    #[inline]
    pub fn of(&self, id: u32) -> Option<&[[f32; 4]]> {
        self.colours.get(self.span(id)?)
    }

    /// Where Gaussian `id`'s entries are in the table, if it has them.
    #[inline]
    fn span(&self, id: u32) -> Option<std::ops::Range<usize>> {
        let i = id as usize;
        let s = *self.start.get(i)?;
        if s == u32::MAX {
            return None;
        }
        let s = s as usize;
        Some(s..s + self.count[i] as usize)
    }

    /// Gaussian `id`'s fitted positions, if the table has them.
    #[inline]
    pub fn positions_of(&self, id: u32) -> Option<&[[f32; 3]]> {
        self.positions.as_ref()?.get(self.span(id)?)
    }

    /// Gaussians with colours in the table.
    pub fn gaussians(&self) -> usize {
        self.start.iter().filter(|&&s| s != u32::MAX).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_travel_with_their_colours() {
        let mut t = VertexColours::with_positions(3);
        let c = [[0.1, 0.2, 0.3, 0.4], [0.5, 0.6, 0.7, 0.8]];
        let p = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]];
        t.set_positions(2, &c, &p).unwrap();
        t.set_positions(0, &c[..1], &p[1..]).unwrap();
        assert_eq!(t.of(2), Some(&c[..]));
        assert_eq!(t.positions_of(2), Some(&p[..]));
        assert_eq!(t.positions_of(0), Some(&p[1..]));
        assert_eq!(t.positions_of(1), None);
        assert_eq!(t.gaussians(), 2);
    }

    #[test]
    fn a_positions_table_refuses_what_would_misalign_it() {
        let mut t = VertexColours::with_positions(2);
        let c = [[0.1, 0.2, 0.3, 0.4]];
        // Colours alone would leave the positions one entry short of the colours.
        assert!(t.set(0, &c).is_err());
        assert!(t.set_positions(0, &c, &[]).is_err());
        assert!(t.set_positions(0, &c, &[[f32::NAN, 0.0, 0.0]]).is_err());
        // Nothing above was stored: the id is still free.
        t.set_positions(0, &c, &[[0.0; 3]]).unwrap();
        assert!(t.set_positions(0, &c, &[[0.0; 3]]).is_err(), "set twice");
        let mut plain = VertexColours::new(1);
        assert!(plain.set_positions(0, &c, &[[0.0; 3]]).is_err());
        assert_eq!(plain.positions_of(0), None);
    }
}
