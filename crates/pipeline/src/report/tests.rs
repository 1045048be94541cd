//! Tests of the report model, its HTML and SVG, and of the pipeline documentation.

mod model {
    use std::path::Path;

    use super::super::svg::ticks;
    use super::super::*;

    #[test]
    fn html_contains_figures_tables_and_images() {
        let mut r = Report::new("t", Path::new("in.tif"), 7);
        let mut s = Section::new("load");
        s.figure("voids", 3);
        s.figure("rmse_m", 0.25);
        s.figure("residual", 1.5e-7);
        s.figure(
            "sizes",
            serde_json::json!({"arches": {"count": 2, "span_m": [12.5, 40.0]}, "long": (0..20).collect::<Vec<_>>()}),
        );
        s.table(
            "round trips",
            &["format", "max-abs"],
            vec![vec!["exr".into(), "0".into()]],
        );
        s.image("dem.png", "a <b>");
        r.push(s);
        let h = r.html();
        assert!(h.contains("<td>voids</td><td>3</td>"));
        assert!(h.contains("<td>rmse_m</td><td>0.2500</td>"));
        assert!(h.contains("<td>residual</td><td>1.5000e-7</td>"), "{h}");
        // Structured figures are rows of fields, not a cell of JSON.
        assert!(h.contains("<td>sizes.arches.count</td><td>2</td>"), "{h}");
        assert!(
            h.contains("<td>sizes.arches.span_m</td><td>[12.5000, 40.0000]</td>"),
            "{h}"
        );
        assert!(
            h.contains(
                "<td>sizes.long</td><td>[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, ... (20 items)]</td>"
            ),
            "{h}"
        );
        assert!(!h.contains("&quot;"), "{h}");
        assert!(h.contains("<td>exr</td><td>0</td>"));
        assert!(h.contains("src=\"dem.png\""));
        assert!(h.contains("a &lt;b&gt;"));
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["stages"][0]["figures"]["voids"], 3);
    }

    #[test]
    fn helpers_render_toc_summary_pairs_plots_and_captions() {
        let mut r = Report::new("t", Path::new("in.tif"), 7);
        r.total_seconds = 4.0;
        let mut s = Section::new("sparse_amplify");
        s.seconds = 3.0;
        s.peak_memory_bytes = Some(3 * 1024 * 1024);
        s.peak_rise_bytes = Some(1024 * 1024);
        s.headline("psnr_db", 41.25);
        s.headline("psnr_db", 41.25);
        s.figure("not_headline", 1);
        s.note("x4 amplification & more");
        s.pair(("a.png", "before"), ("b.png", "after"), "hillshades");
        s.numbers(
            "quality",
            "lower is better",
            &["metric", "ours", "peer"],
            &[
                ("rmse_m", vec![0.123456, f64::NAN]),
                ("n", vec![12.0, 3e-5]),
            ],
        );
        s.plot(
            Plot::new("spectrum", "f", "power")
                .log_log()
                .line("in", [(0.01, 1e4), (0.1, 10.0), (0.0, 5.0)])
                .dashed("fit", [(0.01, 2e4), (0.1, 20.0)]),
        );
        r.push(s);
        let h = r.html();
        assert_eq!(r.stages[0].headlines, ["psnr_db"]);
        // Contents and summary link to the section; the summary shows headlines only.
        assert!(h.contains("<li><a href=\"#stage-sparse_amplify\">sparse_amplify</a></li>"));
        assert!(h.contains("<h2 id=\"stage-sparse_amplify\">"));
        assert!(
            h.contains("<td>3.00</td><td>75 %</td><td>3.0 MiB (+1.0 MiB)</td>"),
            "{h}"
        );
        assert!(
            h.contains("<td class=\"keys\">psnr_db = 41.2500</td>"),
            "{h}"
        );
        assert!(!h.contains("keys\">not_headline"));
        assert!(h.contains("<p>x4 amplification &amp; more</p>"));
        assert!(h.contains("<div class=\"pair\"><figure><img src=\"a.png\""));
        assert!(h.contains("<caption>lower is better</caption>"));
        assert!(
            h.contains("<td>rmse_m</td><td>0.1235</td><td>-</td>"),
            "{h}"
        );
        assert!(h.contains("<td>12</td><td>3.000e-5</td>"), "{h}");
        // The plot: two polylines (the zero-frequency point is dropped on the log axis),
        // one dashed, decade ticks.
        assert_eq!(h.matches("<polyline").count(), 2);
        assert_eq!(h.matches("stroke-dasharray").count(), 2); // line + legend swatch
        assert!(h.contains(">1e-2<") && h.contains(">1e4<"), "{h}");
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(
            json["stages"][0]["plots"][0]["series"][0]["points"][1][1],
            10.0
        );
        assert_eq!(json["stages"][0]["tables"][0]["caption"], "lower is better");
    }

    #[test]
    fn mismatched_tables_are_padded_not_fatal() {
        let mut s = Section::new("x");
        s.numbers("t", "", &["m", "a"], &[("r", vec![1.0, 2.0, 3.0])]);
        s.table("u", &["a", "b", "c"], vec![vec!["1".into()]]);
        assert_eq!(s.tables[0].columns, ["m", "a", "", ""]);
        assert_eq!(s.tables[0].rows[0], ["r", "1", "2", "3"]);
        assert_eq!(s.tables[1].rows[0], ["1", "", ""]);
    }

    #[test]
    fn huge_hillshades_are_reduced_and_pairs_recorded() {
        let (config, tmp) = crate::test_config(None);
        let mut state = State::default();
        let mut section = Section::new("x");
        let mut cx = StageCx {
            config: &config,
            state: &mut state,
            section: &mut section,
        };
        let big = Heightfield::from_fn(4100, 6, 1.0, 1.0, |x, y| (x * y) as f32 * 0.01);
        let small = big.crop(0, 0, 64, 6).unwrap();
        cx.before_after("t", "c", &small, &big).unwrap();
        let png = std::fs::read(tmp.path().join("t_after.png")).unwrap();
        // PNG IHDR: width and height as big-endian u32 at bytes 16..24.
        let w = u32::from_be_bytes(png[16..20].try_into().unwrap());
        assert_eq!(w, 2050, "4100 wide, box-averaged by 2");
        assert_eq!(section.pairs.len(), 1);
        assert_eq!(section.pairs[0].right.caption, "after (4100 x 6)");
    }

    #[test]
    fn number_formatting_and_ticks() {
        assert_eq!(fmt_num(1234.5678), "1235");
        assert_eq!(fmt_num(0.012345), "0.01235");
        assert_eq!(fmt_num(-2.0), "-2");
        assert_eq!(fmt_num(f64::INFINITY), "inf");
        assert_eq!(fmt_num(2.5e7 + 0.5), "2.500e7");
        let t: Vec<f64> = ticks(0.0, 10.0, false).iter().map(|t| t.0).collect();
        assert_eq!(t, [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let t: Vec<f64> = ticks(-3.2, 1.5, true).iter().map(|t| t.0).collect();
        assert_eq!(t, [-3.0, -2.0, -1.0, 0.0, 1.0]);
    }

    #[test]
    fn spectra_are_densities_that_agree_across_grid_sizes() {
        // The same terrain on 10 m cells (256^2) and box-reduced to 20 m (128^2): at the low
        // frequencies both grids resolve, their densities agree (raw FFT power differed by the
        // ratio of the cell counts squared, 16x, and more with the cell areas).
        let fine = relief_heightfield::Heightfield::from_fn(256, 256, 10.0, 10.0, |x, y| {
            let (x, y) = (x as f32, y as f32);
            40.0 * (x * 0.031).sin() * (y * 0.023).cos() + 15.0 * (x * 0.11 + y * 0.07).sin()
        });
        let coarse = fine.downsample_box(2).unwrap();
        let (config, _tmp) = crate::test_config(None);
        let mut state = crate::State::default();
        let mut section = Section::new("t");
        let mut cx = crate::StageCx {
            config: &config,
            state: &mut state,
            section: &mut section,
        };
        cx.spectrum_plot("spectra", &[("fine", &fine), ("coarse", &coarse)]);
        let plot = &section.plots[0];
        assert!(plot.y_label.contains("density"));
        let at = |s: &Series, f: f64| {
            s.points
                .iter()
                .min_by(|a, b| (a.0 - f).abs().total_cmp(&(b.0 - f).abs()))
                .unwrap()
                .1
        };
        for f in [2.0 / 2560.0, 4.0 / 2560.0, 8.0 / 2560.0] {
            let r = at(&plot.series[0], f) / at(&plot.series[1], f);
            assert!((0.5..2.0).contains(&r), "ratio {r} at {f} cycles/m");
        }
    }

    /// The run on a real crop: hillshade pair, spectra and statistics of the overview, per
    /// stage peak memory, and the figures in summary.json.
    #[test]
    fn overview_and_stage_memory_on_a_real_crop() {
        let (config, tmp) = crate::test_config(Some((100, 120, 96, 64)));
        let stages = crate::spec::build_stages(&[
            crate::spec::StageSpec::named("load"),
            crate::spec::StageSpec::named("fill_voids"),
        ])
        .unwrap();
        crate::run(&config, &stages).unwrap();
        for f in ["overview_before.png", "overview_after.png"] {
            assert!(tmp.path().join(f).is_file(), "{f}");
        }
        let summary: serde_json::Value =
            serde_json::from_slice(&std::fs::read(tmp.path().join("summary.json")).unwrap())
                .unwrap();
        let o = &summary["overview"];
        let slope = o["figures"]["spectral_slope_input"].as_f64().unwrap();
        assert!(
            (-4.5..-1.0).contains(&slope),
            "terrain spectral slope {slope}"
        );
        assert_eq!(o["figures"]["slope_histogram_distance_deg"], 0.0);
        assert_eq!(
            o["tables"][0]["rows"][0],
            serde_json::json!(["width", "96", "96"])
        );
        assert_eq!(o["plots"][0]["series"].as_array().unwrap().len(), 2);
        for s in summary["stages"].as_array().unwrap() {
            let peak = s["peak_memory_bytes"].as_u64().unwrap();
            assert!(peak > 1 << 20, "{s}");
            assert!(s["peak_rise_bytes"].as_u64().unwrap() <= peak, "{s}");
        }
        let html = std::fs::read_to_string(tmp.path().join("report.html")).unwrap();
        assert!(html.contains("<a href=\"#overview\">"));
        assert!(html.contains("src=\"overview_after.png\""));
        assert!(html.contains("<svg class=\"plot\""));
    }
}

/// The pipeline documentation stays in step with the code: every registered stage has a
/// section in `docs/PIPELINE.md`, and every spec shown there or kept in `docs/*.json` parses and
/// builds (unknown stages, fields and invalid parameter values are errors).
#[cfg(test)]
mod docs_tests {
    use crate::spec::{PipelineSpec, build_stages, stage_names};

    fn doc() -> String {
        std::fs::read_to_string(crate::test_root().join("docs/PIPELINE.md")).unwrap()
    }

    #[test]
    fn every_stage_is_documented() {
        let doc = doc();
        for name in stage_names() {
            assert!(
                doc.contains(&format!("### `{name}`")),
                "docs/PIPELINE.md has no section for stage `{name}`: add one (what it does, its \
                 parameter table)"
            );
        }
    }

    #[test]
    fn specs_in_the_docs_are_valid() {
        let root = crate::test_root();
        let doc = doc();
        let mut n = 0;
        for block in doc.split("```json\n").skip(1) {
            let json = block.split("```").next().unwrap();
            let spec: PipelineSpec = serde_json::from_str(json)
                .unwrap_or_else(|e| panic!("spec in docs/PIPELINE.md: {e}\n{json}"));
            build_stages(&spec.stages).unwrap_or_else(|e| panic!("{e:#}\n{json}"));
            n += 1;
        }
        assert!(n >= 1);
        let mut files = 0;
        for entry in std::fs::read_dir(root.join("docs")).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "json") {
                let spec = PipelineSpec::read(&path)
                    .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
                let mut config = crate::PipelineConfig::full(&root);
                spec.apply(&mut config);
                assert!(config.input.is_file(), "{}", path.display());
                assert_eq!(spec.stages[0].stage, "load", "{}", path.display());
                files += 1;
            }
        }
        assert!(files >= 1);
    }
}
