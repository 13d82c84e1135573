//! OBJ read in blocks of whole lines, parsed in parallel and applied in order.
//!
//! Why: an exported OBJ runs to gigabytes of text (a `rings` export of a real capture is 1.4 GB),
//! and reading it line by line on one core was most of loading it. A block is parsed on its
//! own into its vertices and statements (faces with the element counts before their line,
//! `o`/`g`/`usemtl`/`mtllib`); applying it to the reading's state is then a short sequential
//! pass, since an index's meaning depends only on the counts before its line.
//!
//! Exactness: the block parser takes on only what it reads the way
//! [`ObjState::line`](crate::obj_read) does: blocks of printable ASCII and the whitespace
//! that trims and splits alike (`plain`), numbers that
//! parse, faces whose indices resolve. A block with anything else (a non-ASCII byte, a number
//! or index that does not parse or resolve, an over-long line, a malformed corner) is read by
//! `ObjState::line` itself, line by line, from the same state, so the result and the first
//! error (its message and line) are those of the line-by-line reading
//! (`obj_read::read_obj_lines`, which the tests compare against).

use std::io::BufRead;
use std::ops::Range;
use std::path::Path;

use glam::Vec3;
use rayon::prelude::*;

use crate::error::{Result, TraceError};
use crate::obj_read::{resolved, too_long, ObjMaterial, ObjObject, ObjState, MAX_LINE};

/// Bytes read for a block (then cut after its last whole line): large enough that a block's
/// overhead (a task, its vectors) is nothing against parsing it, small enough that a batch of
/// them is a few MB.
pub(crate) const BLOCK: usize = 1 << 20;

/// One face corner's indices as written (0: none, for the texture and normal parts).
#[derive(Clone, Copy)]
struct Corner {
    v: i64,
    vt: i64,
    vn: i64,
}

enum Stmt<'t> {
    /// Corners `corners` of the block's list; the vertex, texture and normal counts the block
    /// had defined before the face's line.
    Face {
        corners: Range<u32>,
        before: [u32; 3],
    },
    Object(&'t str),
    Usemtl(&'t str),
    Mtllib(&'t str),
}

/// A block as parsed on its own.
#[derive(Default)]
struct Parsed<'t> {
    positions: Vec<Vec3>,
    colors: Vec<Vec3>,
    n_vt: u32,
    n_vn: u32,
    corners: Vec<Corner>,
    stmts: Vec<Stmt<'t>>,
    /// False: something in the block is for the line-by-line reading to decide.
    clean: bool,
}

/// The block's lines without terminators: `\n`-separated, the last one at the end of the
/// input possibly without its `\n`.
fn lines(block: &[u8]) -> impl Iterator<Item = &[u8]> {
    let body = block.strip_suffix(b"\n").unwrap_or(block);
    let mut start = 0;
    let mut ends = memchr::memchr_iter(b'\n', body).chain(std::iter::once(body.len()));
    std::iter::from_fn(move || {
        if block.is_empty() {
            return None;
        }
        let end = ends.next()?;
        let line = &body[start..end];
        start = end + 1;
        Some(line)
    })
}

/// How many lines [`lines`] yields.
fn line_count(block: &[u8]) -> usize {
    memchr::memchr_iter(b'\n', block).count()
        + usize::from(block.last().is_some_and(|&b| b != b'\n'))
}

/// Whether every byte of `block` is one a clean line may hold: printable ASCII, and the
/// whitespace that `str::trim` and `split_ascii_whitespace` treat alike (tab, carriage
/// return, form feed; the vertical tab is trimmed by one and not split by the other).
/// Branch-free, so that it runs as vector code over the block.
fn plain(block: &[u8]) -> bool {
    block.iter().fold(true, |ok, &b| {
        ok & ((b.wrapping_sub(0x20) < 0x5f)
            | (b == b'\t')
            | (b == b'\n')
            | (b == b'\r')
            | (b == 0x0c))
    })
}

/// The tokens of a line of a [`plain`] block, split on ASCII whitespace as
/// `split_ascii_whitespace` does: in such a block the whitespace bytes (space, tab, carriage
/// return, form feed) are exactly the bytes at or below the space, so one comparison a byte
/// finds them (the generic split was a third of parsing).
struct Tokens<'a> {
    s: &'a [u8],
    i: usize,
}

fn tokens(s: &[u8]) -> Tokens<'_> {
    Tokens { s, i: 0 }
}

impl<'a> Iterator for Tokens<'a> {
    type Item = &'a [u8];

    #[inline]
    fn next(&mut self) -> Option<&'a [u8]> {
        let s = self.s;
        let mut i = self.i;
        while i < s.len() && s[i] <= b' ' {
            i += 1;
        }
        if i == s.len() {
            self.i = i;
            return None;
        }
        let start = i;
        while i < s.len() && s[i] > b' ' {
            i += 1;
        }
        self.i = i;
        Some(&s[start..i])
    }
}

/// A token of a block [`plain`] found to be ASCII.
#[inline]
fn text(t: &[u8]) -> &str {
    debug_assert!(t.is_ascii());
    // SAFETY: `parse_block` parses only blocks whose every byte is ASCII (`plain`), and
    // ASCII is valid UTF-8; `t` is a sub-slice of such a block. Checking each
    // token again was a tenth of reading an export.
    unsafe { std::str::from_utf8_unchecked(t) }
}

fn parse_block(block: &[u8]) -> Parsed<'_> {
    let mut p = Parsed {
        clean: plain(block),
        ..Parsed::default()
    };
    if !p.clean {
        return p;
    }
    for line in lines(block) {
        if line.len() > MAX_LINE || parse_line(line, &mut p).is_none() {
            p.clean = false;
            return p;
        }
    }
    p
}

/// One line into `p`; None where the line is for `ObjState::line` to read.
#[inline]
fn parse_line<'t>(line: &'t [u8], p: &mut Parsed<'t>) -> Option<()> {
    // `plain` held for the block: the line is ASCII, and its whitespace is what both
    // `str::trim` and `split_ascii_whitespace` take as such (one trailing `\r` is the
    // terminator's, the rest trims or splits alike).
    let line = line.strip_suffix(b"\r").unwrap_or(line);
    let trimmed = line.trim_ascii();
    let mut it = tokens(trimmed);
    let Some(key) = it.next() else {
        return Some(());
    };
    let rest = || text(trimmed[key.len()..].trim_ascii());
    match key {
        b"v" => {
            let mut vals = [0f32; 7];
            let mut n = 0;
            for t in it {
                *vals.get_mut(n)? = text(t).parse().ok()?;
                n += 1;
            }
            let c = match n {
                3 | 4 => Vec3::NAN,
                6 => Vec3::new(vals[3], vals[4], vals[5]),
                _ => return None,
            };
            p.positions.push(Vec3::new(vals[0], vals[1], vals[2]));
            p.colors.push(c);
        }
        b"vt" => p.n_vt += 1,
        b"vn" => p.n_vn += 1,
        b"f" => {
            let first = p.corners.len() as u32;
            for c in it {
                let mut parts = c.split(|&b| b == b'/');
                let index = |t: &[u8]| -> Option<i64> {
                    let i: i64 = text(t).parse().ok()?;
                    (i != 0).then_some(i)
                };
                let v = index(parts.next()?)?;
                let mut part = || match parts.next() {
                    Some(t) if !t.is_empty() => index(t),
                    _ => Some(0),
                };
                let (vt, vn) = (part()?, part()?);
                if parts.next().is_some() {
                    return None;
                }
                p.corners.push(Corner { v, vt, vn });
            }
            let end = p.corners.len() as u32;
            if end - first < 3 {
                return None;
            }
            let before = [p.positions.len() as u32, p.n_vt, p.n_vn];
            p.stmts.push(Stmt::Face {
                corners: first..end,
                before,
            });
        }
        b"o" | b"g" => p.stmts.push(Stmt::Object(rest())),
        b"usemtl" => p.stmts.push(Stmt::Usemtl(rest())),
        b"mtllib" => p.stmts.push(Stmt::Mtllib(rest())),
        _ => {}
    }
    Some(())
}

/// The mesh vertex of every face corner of the block, in corner order, where every index of
/// its faces (vertex, texture and normal) resolves against the counts before its line;
/// None where one does not.
fn resolve_corners<F>(state: &ObjState<'_, F>, p: &Parsed<'_>) -> Option<Vec<u32>> {
    let base = [state.positions.len(), state.n_vt, state.n_vn];
    let mut out = Vec::with_capacity(p.corners.len());
    for s in &p.stmts {
        let Stmt::Face { corners, before } = s else {
            continue;
        };
        let count = |k: usize| base[k] + before[k] as usize;
        let (nv, nvt, nvn) = (count(0), count(1), count(2));
        for c in &p.corners[corners.start as usize..corners.end as usize] {
            let v = resolved(c.v, nv)?;
            let other = |i: i64, n: usize| i == 0 || resolved(i, n).is_some();
            if !(other(c.vt, nvt) && other(c.vn, nvn)) {
                return None;
            }
            out.push(v as u32);
        }
    }
    Some(out)
}

/// Apply block `block` (its lines numbered from `first_line`) to the reading's state.
fn apply<F: FnMut(&str) -> Option<Vec<ObjMaterial>>>(
    state: &mut ObjState<'_, F>,
    block: &[u8],
    p: Parsed<'_>,
    first_line: usize,
) -> Result<()> {
    let verts = if p.clean {
        resolve_corners(state, &p)
    } else {
        None
    };
    let Some(verts) = verts else {
        for (i, line) in lines(block).enumerate() {
            let n = first_line + i;
            if line.len() > MAX_LINE {
                return Err(too_long(state.path, n));
            }
            state.line(line.strip_suffix(b"\r").unwrap_or(line), n)?;
        }
        return Ok(());
    };
    state.positions.extend_from_slice(&p.positions);
    state.colors.extend_from_slice(&p.colors);
    for s in &p.stmts {
        match s {
            Stmt::Face { corners, .. } => {
                // Faces' corners are consecutive in the block's list, as in `verts`.
                let c = &verts[corners.start as usize..corners.end as usize];
                for k in 1..c.len() - 1 {
                    state.cur.tris.push([c[0], c[k], c[k + 1]]);
                }
            }
            Stmt::Object(name) => state.object(name),
            Stmt::Usemtl(name) => state.usemtl(name),
            Stmt::Mtllib(name) => state.mtllib(name),
        }
    }
    state.n_vt += p.n_vt as usize;
    state.n_vn += p.n_vn as usize;
    Ok(())
}

/// Append up to `more` bytes of `r` to `buf`; true at the end of the input.
fn fill(r: &mut impl BufRead, buf: &mut Vec<u8>, more: usize) -> std::io::Result<bool> {
    let target = buf.len() + more;
    while buf.len() < target {
        let avail = r.fill_buf()?;
        if avail.is_empty() {
            return Ok(true);
        }
        let n = avail.len().min(target - buf.len());
        buf.extend_from_slice(&avail[..n]);
        r.consume(n);
    }
    Ok(false)
}

/// Read the next block of whole lines (about `block` bytes, after the `carry` of the last
/// one) into `blocks`, keeping the partial line after it in `carry`; at the end of the input,
/// the last line even without its `\n`.
fn next_block(
    r: &mut impl BufRead,
    carry: &mut Vec<u8>,
    block: usize,
    blocks: &mut Vec<Vec<u8>>,
) -> End {
    let mut buf = std::mem::take(carry);
    let mut scanned = 0;
    loop {
        let eof = match fill(r, &mut buf, block.max(1)) {
            Ok(eof) => eof,
            Err(e) => {
                // The whole lines read before the error are read (and may hold an earlier
                // error); the error is the next line's.
                if let Some(i) = memchr::memrchr(b'\n', &buf) {
                    buf.truncate(i + 1);
                    blocks.push(buf);
                }
                return End::Io(e);
            }
        };
        match memchr::memrchr(b'\n', &buf[scanned..]) {
            Some(i) => {
                *carry = buf.split_off(scanned + i + 1);
                blocks.push(buf);
                if !eof {
                    return End::More;
                }
                if !carry.is_empty() {
                    blocks.push(std::mem::take(carry));
                }
                return End::Eof;
            }
            None if eof => {
                if !buf.is_empty() {
                    blocks.push(buf);
                }
                return End::Eof;
            }
            None if buf.len() > MAX_LINE => return End::TooLong,
            None => scanned = buf.len(),
        }
    }
}

/// How a batch of blocks ended.
enum End {
    More,
    Eof,
    /// The line after the batch is longer than [`MAX_LINE`].
    TooLong,
    Io(std::io::Error),
}

/// [`crate::obj_read::read_obj`] with blocks of about `block` bytes.
pub(crate) fn read_blocks(
    r: &mut impl BufRead,
    path: &Path,
    load_mtl: impl FnMut(&str) -> Option<Vec<ObjMaterial>>,
    block: usize,
) -> Result<(Vec<ObjObject>, Vec<ObjMaterial>)> {
    let mut state = ObjState::new(path, load_mtl);
    let batch = rayon::current_num_threads().max(1) * 2;
    let mut carry: Vec<u8> = Vec::new();
    let mut line = 0usize;
    loop {
        let mut blocks: Vec<Vec<u8>> = Vec::with_capacity(batch);
        let mut end = End::More;
        while blocks.len() < batch && matches!(end, End::More) {
            end = next_block(r, &mut carry, block, &mut blocks);
        }
        let parsed: Vec<Parsed<'_>> = blocks.par_iter().map(|b| parse_block(b)).collect();
        for (b, p) in blocks.iter().zip(parsed) {
            apply(&mut state, b, p, line + 1)?;
            line += line_count(b);
        }
        match end {
            End::More => {}
            End::Eof => return Ok(state.finish()),
            End::TooLong => return Err(too_long(path, line + 1)),
            End::Io(e) => {
                return Err(TraceError::format(
                    path,
                    format!("line {}: cannot read: {e}", line + 1),
                ))
            }
        }
    }
}
