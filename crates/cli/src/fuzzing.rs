//! Entry points of the fuzz targets in `fuzz/`: the parsers of the files relief takes from
//! places other people or jobs may write (tile plan manifests and records, pipeline specs).
//! Each may refuse its input and must never panic; what it accepts must satisfy the checks
//! asserted here. Not an API: the functions exist for `cargo fuzz`.

use std::path::Path;

use crate::tile_manifest::{FileSum, is_inside_name, parse_manifest, parse_record, tile_name};

/// A tile plan manifest: an accepted one has a prepared file inside the plan folder and every
/// task's window non-empty and inside the output.
pub fn tile_manifest(bytes: &[u8]) {
    if let Ok(m) = parse_manifest(bytes, Path::new("manifest.json")) {
        assert!(is_inside_name(&m.prepared.path), "{}", m.prepared.path);
        assert!(m.tasks >= 1 && m.tasks <= crate::tile_manifest::MAX_TASKS);
        for i in [0, m.tasks / 2, m.tasks - 1] {
            let [x, y, w, h] = m.window(i);
            assert!(w > 0 && h > 0 && x + w <= m.output.width && y + h <= m.output.height);
        }
    }
}

/// A tile record: an accepted one names its own tile's file and window.
pub fn tile_record(bytes: &[u8]) {
    let m = crate::tile_manifest::sample(0);
    for i in [0, 1, 7] {
        if let Some(r) = parse_record(&m, i, bytes) {
            assert_eq!(r.file.path, tile_name(i));
            assert_eq!(r.window, m.window(i));
            let _: &FileSum = &r.file;
        }
    }
}

/// A task record of a flow plan: an accepted one lists only the files its task writes,
/// inside the plan folder.
pub fn flow_record(bytes: &[u8]) {
    let phases = relief_landscape::flow::tiled::PHASES;
    let m = crate::tile_manifest::sample(phases);
    for phase in 1..=phases {
        if let Some(files) = crate::commands::tile::record_files(&m, phase, 1, bytes) {
            assert!(files.iter().all(|f| is_inside_name(f)), "{files:?}");
        }
    }
}

/// A pipeline spec (`relief run --spec`): parsed and every stage built, or refused.
pub fn run_spec(bytes: &[u8]) {
    if let Ok(spec) = crate::pipeline::spec::PipelineSpec::from_bytes(bytes, Path::new("spec.json"))
    {
        assert!(!spec.stages.is_empty());
    }
}
