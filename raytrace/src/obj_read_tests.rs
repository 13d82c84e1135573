//! The block reader (`obj_block`) against the line-by-line reading (`read_obj_lines`): the
//! same objects, materials and first error, on random OBJ text that mixes every statement the
//! reader knows with the malformed lines it must refuse, cut into blocks of every size.

use std::io::{BufReader, Read};
use std::path::Path;

use crate::obj_block::read_blocks;
use crate::obj_read::{read_obj_lines, ObjMaterial, MAX_LINE};
use crate::test_rng::unit;

/// A material per library name, so that `usemtl` finds some and misses others.
fn library(name: &str) -> Option<Vec<ObjMaterial>> {
    (!name.contains("missing")).then(|| {
        vec![ObjMaterial {
            name: format!("m_{name}"),
            diffuse: Some([0.5, 0.25, 1.0]),
            dissolve: None,
        }]
    })
}

/// Random OBJ text: mostly well-formed statements, with a malformed line about once in
/// `bad_every` lines (0: never).
fn random_obj(seed: u64, lines: usize, bad_every: u64) -> Vec<u8> {
    let mut draw = unit(seed);
    let mut pick = move |n: u64| (draw() * n as f64) as u64 % n.max(1);
    let (mut nv, mut nvt, mut nvn) = (0i64, 0i64, 0i64);
    let mut out = Vec::new();
    for _ in 0..lines {
        let ws = [" ", "  ", "\t", " \t "][pick(4) as usize];
        let end = ["\n", "\n", "\n", "\r\n"][pick(4) as usize];
        let idx = |pick: &mut dyn FnMut(u64) -> u64, n: i64| -> i64 {
            if n == 0 {
                return 1;
            }
            match pick(3) {
                0 => -(pick(n as u64) as i64) - 1,
                _ => pick(n as u64) as i64 + 1,
            }
        };
        let line = if bad_every > 0 && pick(bad_every) == 0 {
            let n = nv.max(1);
            match pick(19) {
                16 => "v\u{c}1 2\r3".into(),
                17 => "\u{c}o\r name\t".into(),
                18 => "g\u{b}".into(),
                0 => format!("v 1 2{ws}x"),
                1 => "v 1 2 3 4 5".into(),
                2 => "v 1 2 3 4 5 6 7 8".into(),
                3 => format!("f 1 2{ws}"),
                4 => format!("f {} 1 1", n + 5),
                5 => "f 0 1 1".into(),
                6 => "f 1/1/1/1 1 1".into(),
                7 => format!("f 1/{} 1 1", nvt + 3),
                8 => format!("f 1//{} 1 1", -(nvn + 2)),
                9 => "f a 1 1".into(),
                10 => "o caf\u{e9}".into(),
                11 => "\u{a0}v 1 2 3".into(),
                12 => "v\u{b}1 2 3".into(),
                13 => format!("# {}", "x".repeat(MAX_LINE + 3)),
                14 => "f +1 1 1".into(),
                _ => String::from_utf8_lossy(b"# \xff").into_owned() + "\u{fffd}",
            }
        } else {
            match pick(14) {
                0..=3 => {
                    nv += 1;
                    let c = |pick: &mut dyn FnMut(u64) -> u64| pick(1000) as f32 / 997.0;
                    let (x, y, z) = (c(&mut pick) * 3.0 - 1.0, -c(&mut pick), c(&mut pick));
                    match pick(3) {
                        0 => format!("v{ws}{x}{ws}{y} {z}"),
                        1 => format!("v {x} {y} {z} 1"),
                        _ => format!("v {x} {y} {z} {} 0.5 1e-3", c(&mut pick)),
                    }
                }
                4 => {
                    nvt += 1;
                    "vt 0.5 0.5".into()
                }
                5 => {
                    nvn += 1;
                    "vn 0 0 1".into()
                }
                6..=9 if nv > 0 => {
                    let k = 3 + pick(3) as usize;
                    let corners: Vec<String> = (0..k)
                        .map(|_| {
                            let v = idx(&mut pick, nv);
                            match pick(4) {
                                0 => format!("{v}"),
                                1 if nvt > 0 => format!("{v}/{}", idx(&mut pick, nvt)),
                                2 if nvn > 0 => format!("{v}//{}", idx(&mut pick, nvn)),
                                3 if nvt > 0 && nvn > 0 => {
                                    format!("{v}/{}/{}", idx(&mut pick, nvt), idx(&mut pick, nvn))
                                }
                                _ => format!("{v}/"),
                            }
                        })
                        .collect();
                    format!("{ws}f {}", corners.join(ws))
                }
                10 => ["o part", "g  other part ", "o", "g\tsplit"][pick(4) as usize].into(),
                11 => ["usemtl m_lib", "usemtl m_none", "usemtl  m_lib2"][pick(3) as usize].into(),
                12 => ["mtllib lib", "mtllib missing", "mtllib lib2"][pick(3) as usize].into(),
                _ => ["# comment", "", "s off", "   ", "l 1 2"][pick(5) as usize].into(),
            }
        };
        out.extend_from_slice(line.as_bytes());
        out.extend_from_slice(end.as_bytes());
    }
    if pick(2) == 0 {
        // The last line without its terminator.
        out.extend_from_slice(b"v 0 0 0");
    }
    out
}

fn both(data: &[u8], block: usize) -> (String, String) {
    let path = Path::new("t.obj");
    let want = read_obj_lines(&mut &data[..], path, library);
    let got = read_blocks(&mut &data[..], path, library, block);
    let show = |r: crate::error::Result<_>| match r {
        Ok(v) => format!("{v:?}"),
        Err(e) => format!("error: {e}"),
    };
    (show(got), show(want))
}

#[test]
fn blocks_read_what_lines_read() {
    let (mut ok, mut err) = (0, 0);
    for seed in 0..60u64 {
        let bad_every = [0, 0, 40, 200, 1000][(seed % 5) as usize];
        let data = random_obj(seed, 400 + 37 * seed as usize, bad_every);
        for block in [1, 7, 64, 1000, 1 << 20] {
            let (got, want) = both(&data, block);
            assert_eq!(got, want, "seed {seed}, block {block}");
        }
        if both(&data, 1 << 20).1.starts_with("error") {
            err += 1;
        } else {
            ok += 1;
        }
    }
    // Both outcomes are exercised (at the time of writing: 27 read, 33 refused).
    assert!(ok > 10 && err > 10, "{ok} read, {err} refused");
}

/// A reader that fails after `at` bytes.
struct Failing<'a> {
    data: &'a [u8],
    at: usize,
}

impl Read for Failing<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.at == 0 {
            return Err(std::io::Error::other("device gone"));
        }
        let n = buf.len().min(self.at).min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        self.at -= n;
        Ok(n)
    }
}

#[test]
fn a_read_error_names_the_line_it_cut() {
    let data = random_obj(7, 300, 0);
    let path = Path::new("t.obj");
    for at in [0, 1, 100, 2000, data.len() / 2] {
        let reader = |cap| BufReader::with_capacity(cap, Failing { data: &data, at });
        let want = read_obj_lines(&mut reader(64), path, library).unwrap_err();
        for block in [5, 300, 1 << 20] {
            let got = read_blocks(&mut reader(64), path, library, block).unwrap_err();
            assert_eq!(got.to_string(), want.to_string(), "at {at}, block {block}");
        }
    }
}
