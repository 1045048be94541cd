//! `relief validate --exemplar E [...] (--guide G | --guide-from DEM --blur S) [--categories MAP]
//! [--size WxH] --patch P --overlap O`: the input check of section 4 of Cruz et al. 2015 alone.
//! Prints every failing guide block with its candidate count and needed height range, the
//! missing height ranges, the exemplars' ranges and a small covering subset of exemplars; exits
//! non-zero when the validation fails. Without a guide, checks the exemplars' compatibility.

use anyhow::{Context, Result, bail};
use relief_patch_synth::ValidationReport;

use crate::ctx::Ctx;

/// Arguments of `relief validate`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    pub(crate) synth: crate::synth_args::SynthArgs,
}

/// The report as printed on stdout.
pub(crate) fn format_report(rep: &ValidationReport, names: &[String]) -> String {
    let mut s = String::new();
    let name = |i: usize| names.get(i).cloned().unwrap_or_else(|| format!("#{i}"));
    s.push_str(&format!(
        "grid:            {} x {} blocks\n",
        rep.grid.0, rep.grid.1
    ));
    s.push_str(&format!(
        "needs:           {} candidate patches per block (match tolerance {:.2} m RMS)\n",
        rep.min_candidates, rep.tolerance
    ));
    for (i, r) in rep.exemplar_ranges.iter().enumerate() {
        s.push_str(&format!(
            "exemplar {i}:      {} covers {:.1} .. {:.1} m\n",
            name(i),
            r.0,
            r.1
        ));
    }
    if !rep.blocks.is_empty() {
        let min = rep.blocks.iter().map(|b| b.candidates).min().unwrap_or(0);
        s.push_str(&format!(
            "blocks:          {} of {} fail (fewest candidates: {min})\n",
            rep.failing.len(),
            rep.blocks.len()
        ));
        for &i in &rep.failing {
            let b = &rep.blocks[i];
            s.push_str(&format!(
                "failing block:   ({}, {}) at x={} y={}: {} candidates, guide heights {:.1} .. {:.1} m\n",
                b.gx, b.gy, b.x, b.y, b.candidates, b.guide_range.0, b.guide_range.1
            ));
        }
        for r in &rep.missing_ranges {
            s.push_str(&format!("missing heights: {:.1} .. {:.1} m\n", r.0, r.1));
        }
        let cover: Vec<String> = rep.cover.iter().map(|&i| name(i)).collect();
        s.push_str(&format!("covering subset: {}\n", cover.join(", ")));
        for (gx, gy) in &rep.uncovered {
            s.push_str(&format!(
                "uncoverable:     block ({gx}, {gy}) (no subset of the exemplars covers it)\n"
            ));
        }
    }
    for c in &rep.compatibility {
        s.push_str(&format!(
            "compatibility:   exemplar {} {}: {} of {} sampled patches match other exemplars (~{} in all) {}\n",
            c.exemplar,
            name(c.exemplar),
            c.compatible,
            c.checked,
            c.estimated_compatible,
            if c.ok { "ok" } else { "TOO FEW" }
        ));
    }
    s.push_str(&format!(
        "result:          {}\n",
        if rep.ok { "ok" } else { "FAILED" }
    ));
    s
}

/// Builds the exemplar index, runs the validation, prints the report; an error (non-zero exit)
/// when it fails.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    ctx.check_outputs(&args.synth.input_paths(), &args.synth.output_paths())?;
    let job = args.synth.job()?;
    let inputs = args.synth.inputs(ctx)?;
    args.synth.preflight(&job, &inputs, ctx)?;
    let progress = ctx.progress();
    let out = job
        .run(inputs, &progress)
        .map_err(|e| args.synth.job_error(e))
        .context("validation failed")?;
    if let (Some(g), Some(p)) = (&out.guide, &args.synth.guide_out) {
        ctx.write_raster(p, g)?;
    }
    drop(progress);
    args.synth.note_figures(&out.figures, ctx);
    let names: Vec<String> = args
        .synth
        .exemplars
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let rep = out.report;
    #[allow(clippy::print_stdout)]
    {
        print!("{}", format_report(&rep, &names));
    }
    if !rep.ok {
        if rep.blocks.is_empty() {
            bail!("validation failed: some exemplars are incompatible with the others");
        }
        let ranges: Vec<String> = rep
            .missing_ranges
            .iter()
            .map(|r| format!("{:.0}..{:.0} m", r.0, r.1))
            .collect();
        bail!(
            "validation failed: {} of {} guide blocks have fewer than {} candidates (missing heights {}){}",
            rep.failing.len(),
            rep.blocks.len(),
            rep.min_candidates,
            if ranges.is_empty() {
                "none".to_string()
            } else {
                ranges.join(", ")
            },
            rep.suggestion
                .map_or_else(String::new, |h| format!("; {h}"))
        );
    }
    Ok(())
}
