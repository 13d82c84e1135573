//! The demo's `report.md`: the picture, then what a user decides on (which export for which
//! viewer, at what accuracy and size, measured in this run), what each stage cost, the
//! dynamic street's part, and every measured image.

use std::fmt::Write as _;

use super::capture::{CaptureRun, Output};
use super::stages::Stages;
use super::street::StreetRun;

/// Heading of the decision table; the report leads with it after the picture.
pub const DECISION_HEADING: &str = "## Which export for which viewer";

/// File name of the picture next to the report.
pub const PICTURE: &str = "overview.png";

/// `12.3 MB`, `45 kB`.
pub fn size(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e6 {
        format!("{:.1} MB", b / 1e6)
    } else if b >= 1e3 {
        format!("{:.0} kB", b / 1e3)
    } else {
        format!("{bytes} B")
    }
}

/// `31.42 dB`, `∞` for an identical image.
pub fn db(p: f64) -> String {
    if p.is_infinite() && p > 0.0 {
        "∞ (identical)".into()
    } else {
        format!("{p:.2} dB")
    }
}

/// The picture's caption line under an output: its PSNR on the picture's view and its size.
pub fn caption(o: &Output) -> String {
    let p = o.psnr.first().copied().unwrap_or(f64::NAN);
    let p = if o.key == "native" {
        "reference".to_string()
    } else {
        format!("PSNR {}", db(p))
    };
    match o.bytes {
        Some(b) => format!("{p} · {}", size(b)),
        None => p,
    }
}

/// The PSNR cell of an output: mean over the views and the worst view.
fn psnr_cell(o: &Output) -> String {
    if o.psnr.len() > 1 {
        format!(
            "**{}** (worst {})",
            db(o.mean_psnr()),
            db(o.worst_psnr()).trim_end_matches(" dB")
        )
    } else {
        format!("**{}**", db(o.mean_psnr()))
    }
}

fn file_cell(o: Option<&Output>) -> String {
    match o.and_then(|o| o.file.as_ref().zip(o.bytes)) {
        Some((f, b)) => format!("[`{f}`]({f}), {}", size(b)),
        None => "–".into(),
    }
}

/// The decision table: one row per way of taking the capture away.
pub fn decision_table(run: &CaptureRun) -> String {
    let o = |k: &str| run.output(k);
    let cell = |k: &str| o(k).map_or("–".into(), psnr_cell);
    let mut s = format!("{DECISION_HEADING}\n\n");
    let _ = writeln!(
        s,
        "PSNR against native splatting, mean (and worst) over the {} measured views at {}×{}; \
         higher is better, above about 35 dB differences are hard to see.\n",
        run.views.len(),
        run.width,
        run.height
    );
    s.push_str("| viewer | take | file, size | PSNR vs native | why |\n|---|---|---|---|---|\n");
    let tri = |k: &str| {
        o(k).and_then(|o| o.triangles).map_or(String::new(), |t| {
            format!(", {:.2} M triangles", t as f64 / 1e6)
        })
    };
    let _ = writeln!(
        s,
        "| any glTF viewer (Blender Cycles and EEVEE, three.js, Babylon.js), views of a known size | \
         distilled GLB: `convert {n} --distill --distill-width W --distill-height H -o OUT.glb` (here {w}×{h}, `--views orbit:{f} --iterations {i}`) | {} | {} | \
         the mesh's colours and opacities fitted to native splatting at that size{}; made for its fitting size (seen at twice the size it loses, docs/distill.md) |",
        file_cell(o("distilled")),
        cell("distilled"),
        tri("distilled"),
        w = run.width,
        h = run.height,
        f = run.fit_views,
        i = run.distill.report.iterations,
        n = run.input.display(),
    );
    let _ = writeln!(
        s,
        "| the same viewers, sizes not known in advance | default GLB: `convert {} -o OUT.glb` (texture profile, laid out for stock viewers) | {} | {} | \
         one textured quad per Gaussian{}; Cycles within 0.1 dB and three.js within 0.4 dB of the tracer that measured it (docs/blender.md, docs/viewers.md) |",
        run.input.display(),
        file_cell(o("glb")),
        cell("glb"),
        tri("glb"),
    );
    let _ = writeln!(
        s,
        "| splat viewers that read `.spz` | `.spz`: `convert {} -o OUT.spz` | {} | {} | \
         the Gaussians themselves, quantised (SPZ v3); the figure is native splatting of the file read back |",
        run.input.display(),
        file_cell(o("spz")),
        cell("spz"),
    );
    let _ = writeln!(
        s,
        "| glTF splat viewers (`KHR_gaussian_splatting`, e.g. Babylon.js 9) | `convert {} --splats -o OUT.glb` (`--khr-compression spz`: about 10× smaller) | {} | {} | \
         float32 Gaussians, lossless; a viewer's own splatting differs from 3DGS (Babylon.js: 31.48 dB on this capture, docs/viewers.md) |",
        run.input.display(),
        file_cell(o("khr")),
        cell("khr"),
    );
    let _ = writeln!(
        s,
        "| 3D Tiles (CesiumJS, 3d-tiles-renderer), large scenes | `convert {} --tiles DIR` | not run by the demo | – | \
         levels of detail with measured geometric errors; leaves hold the Gaussians unchanged (SPZ-compressed by default); CesiumJS and 3d-tiles-renderer are measured in docs/tiles.md |",
        run.input.display(),
    );
    s.push_str(
        "| tools without glTF (OBJ) | `convert CAPTURE -o OUT.obj` (rings profile) | not run by the demo (a rings mesh of 131k Gaussians is about 14 M triangles) | \
         21.12 dB on `fourth_st`, 8.3 dB under the GLB of the same profile (docs/meshes.md) | OBJ has no alpha: every splat becomes opaque |\n",
    );
    let _ = writeln!(
        s,
        "| a GES-style renderer (opaque surfels + Gaussians) | `hybrid {} --camera …`, or `convert --surfels -o OUT.glb` | – | {} | \
         flat opaque Gaussians drawn as opaque surfels, the rest blended (sorted) in front of them |",
        run.input.display(),
        cell("hybrid"),
    );
    let _ = writeln!(
        s,
        "| ray tracing (secondary rays, LiDAR, shadows) | `trace {} --mode gaussian` | – | {} | \
         the Gaussians ray-traced (3DGRT-style) with a pixel footprint, no mesh in between |",
        run.input.display(),
        cell("trace-gaussian"),
    );
    s
}

/// The whole `report.md` of the demo.
pub fn markdown(
    run: &CaptureRun,
    street: Option<&StreetRun>,
    all: &Stages,
    load: Option<f64>,
) -> String {
    let mut s = format!("# splatbridge demo: `{}`, a real capture\n\n", run.name);
    let titles: Vec<String> = run
        .outputs
        .iter()
        .filter(|o| super::PICTURE_KEYS.contains(&o.key))
        .map(|o| o.title.clone())
        .collect();
    let _ = writeln!(
        s,
        "![{}, PSNR against native under each]({PICTURE})\n",
        titles.join(" · ")
    );
    let _ = writeln!(
        s,
        "`{}` ({}): {} Gaussians, SH degree {}, {}. The picture is view `{}` of the orbit whose even \
         cameras are the distillation's {} fitting views: half-way between two of them, never fitted itself.\n",
        run.input.display(),
        provenance(&run.input),
        thousands(run.gaussians),
        run.sh_degree,
        size(run.input_bytes),
        run.views.first().map_or("", String::as_str),
        run.fit_views,
    );
    s.push_str(&decision_table(run));
    let _ = writeln!(
        s,
        "\nDistillation: {}. A longer fit gains more (default `convert --distill`: 48 views, 60 steps; \
         `fourth_st` texture 35.67 dB on held-back views at 240×180, docs/distill.md).\n",
        run.distill.description
    );
    s.push_str("## What each stage cost\n\n");
    s.push_str(&all.markdown());
    s.push_str(
        "\nWall and CPU seconds of this run on this machine (CPU: user + system over all cores; \
         the machine may be shared, so wall time alone can mislead). Tracer and BVH times are \
         inside their stages.",
    );
    if let Some(l) = load {
        let _ = write!(s, " Load average (1 minute) at the end of the run: {l:.1}.");
    }
    s.push('\n');
    if let Some(st) = street {
        let _ = writeln!(
            s,
            "\n## The dynamic part: the street\n\n\
             [`street/report.md`](street/report.md): the built-in street scene ({} Gaussians, {} moving cars) \
             as an animated GLB ([`street/street.glb`](street/street.glb), {}, {} triangles: the cars are \
             animated glTF nodes) and a first-frame OBJ, compared against native at {} images. The street is \
             synthetic (flat, opaque discs), so its figures are lower than a trained capture's; its report says why.",
            thousands(st.gaussians),
            st.objects,
            size(st.glb_bytes),
            st.glb_triangles,
            st.records.len(),
        );
        let rows = crate::measure::report::summary::summarize(&st.records);
        s.push_str("\n| renderer | profile | file | mean PSNR dB |\n|---|---|---|---|\n");
        for r in rows {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} |",
                r.renderer,
                r.profile,
                r.format,
                r.mean_psnr
                    .map_or("∞ (reference)".into(), |p| format!("{p:.2}"))
            );
        }
    }
    s.push_str("\n## Every image of the capture\n\n");
    s.push_str(&crate::measure::report::markdown_table(&run.records, true));
    s
}

/// `131199` as `131,199`.
pub fn thousands(n: usize) -> String {
    let d = n.to_string();
    let mut out = String::new();
    for (i, c) in d.chars().enumerate() {
        if i > 0 && (d.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Where the capture comes from, for the shipped one.
fn provenance(input: &std::path::Path) -> &'static str {
    if input.ends_with(super::capture::SHIPPED_CAPTURE) {
        "PDAL's test data, BSD-3-Clause; see `fixtures/real/README.md`"
    } else {
        "given with `--capture`"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_decibels_read_as_a_person_writes_them() {
        assert_eq!(size(3_110_775), "3.1 MB");
        assert_eq!(size(45_300), "45 kB");
        assert_eq!(size(12), "12 B");
        assert_eq!(thousands(131_199), "131,199");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(1_000_000), "1,000,000");
        assert_eq!(db(31.416), "31.42 dB");
        assert_eq!(db(f64::INFINITY), "∞ (identical)");
    }

    #[test]
    fn captions_say_psnr_and_size() {
        let o = Output {
            key: "glb",
            title: "default GLB".into(),
            file: Some("x.glb".into()),
            bytes: Some(63_000_000),
            triangles: Some(1_400_000),
            psnr: vec![30.123, 29.0],
            milliseconds: vec![1.0, 1.0],
        };
        assert_eq!(caption(&o), "PSNR 30.12 dB · 63.0 MB");
        assert!((o.mean_psnr() - 29.5615).abs() < 1e-9);
        assert_eq!(o.worst_psnr(), 29.0);
        let native = Output {
            key: "native",
            bytes: None,
            psnr: vec![f64::INFINITY],
            ..o
        };
        assert_eq!(caption(&native), "reference");
        assert_eq!(native.mean_psnr(), f64::INFINITY);
    }
}
