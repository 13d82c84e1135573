//! What `convert --distill` prints about the fit it made (`splatbridge::distill::run::Outcome`).

use splatbridge::distill::run::Outcome;

use super::distill_args::DistillArgs;

/// Print the fit's summary to stderr: views, set-up, validation, backtrack, stop, the guard's
/// refusal, the check against the undistilled export and the held-back change.
pub fn print(out: &Outcome, args: &DistillArgs) {
    let r = &out.report;
    eprintln!("distilled: {}", out.description);
    eprintln!("  parameters: {} ({} vertices)", r.params, r.vertices);
    eprintln!(
        "  set-up {:.1} s (native targets {:.1} s, hit recording {:.1} s), {} hits ({} views kept, {} streamed, {:.0} MB), loss {:.4} → {:.4}",
        r.setup_seconds,
        r.setup_targets_seconds,
        r.setup_record_seconds,
        r.hits,
        r.stored_views,
        r.streamed_views,
        r.hit_bytes as f64 / 1e6,
        r.loss_first,
        r.loss_last
    );
    if r.validation_views > 0 {
        eprintln!(
            "  validation PSNR ({} views): {:.2} dB → {:.2} dB (iteration {} of {} kept)",
            r.validation_views,
            r.validation_start,
            r.validation_kept,
            r.kept_iteration,
            r.iterations
        );
    }
    if let Some((at, to)) = r.backtracked {
        eprintln!(
            "  the guard refused iteration {at}: the fit went back to iteration {to} and went on with ε {} (--distill-eps-backtrack)",
            args.distill_eps_backtrack
        );
    }
    if r.stopped_early {
        let (n, kept, all) = (args.distill_patience, r.kept_iteration, args.iterations);
        let s = if n == 1 { "" } else { "s" };
        eprintln!("  stopped after iteration {}: {n} validation{s} in a row without progress (no admissible iteration better than iteration {kept}, none closer to admissible; --distill-patience 0 runs all {all})", r.iterations);
    }
    if let Some(v) = &out.best_refused {
        let (view, change) = v.worst_view();
        // Rounded up, so the tolerance named does admit the iteration.
        let tolerance = (-change * 100.0).ceil() / 100.0;
        eprintln!(
            "  the guard refused iteration {} (validation mean {:.2} dB, {:+.2}): validation view {} lost {:.2} dB; --distill-guard-tolerance {tolerance:.2} keeps it",
            v.iteration,
            v.mean,
            v.mean - r.validation_kept,
            view + 1,
            -change,
        );
    }
    if let Some(f) = &out.undistilled {
        if let Some((view, change)) = f.worst() {
            if f.kept_undistilled {
                eprintln!(
                    "  the undistilled export is written: iteration {} is {:.3} dB below it at validation view {} (the widened mesh loses there; --distill-footprint off fits the undistilled mesh)",
                    r.kept_iteration,
                    -change,
                    view + 1
                );
            } else {
                eprintln!(
                    "  against the undistilled export: validation views {change:+.3} dB at worst (view {})",
                    view + 1
                );
            }
        }
    }
    if let (Some((a, b)), Some((worst, median))) = (out.held_back, out.held_back_change) {
        let near = splatbridge::distill::near_unless_reference(args.distill_near)
            .map_or(String::new(), |z| format!(", near plane {z}"));
        eprintln!(
            "  held-back PSNR against native ({} views{near}): {a:.2} dB → {b:.2} dB (change: worst {worst:+.2}, median {median:+.2} dB)",
            out.held_back_views
        );
    }
}
