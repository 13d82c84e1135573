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
