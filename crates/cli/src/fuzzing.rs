//! Entry points of the fuzz targets in `fuzz/`: the parsers of the files relief takes from
//! places other people or jobs may write (tile plan manifests and records, pipeline specs).
//! Each may refuse its input and must never panic; what it accepts must satisfy the checks
//! asserted here. Not an API: the functions exist for `cargo fuzz`.

use std::path::Path;

use crate::tile_manifest::{
    FORMAT, FileSum, Manifest, OutputGrid, VERSION, bytes_sum, is_inside_name, parse_manifest,
    parse_record, tile_name,
};

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

/// A manifest of 4 x 2 tasks of 32 px over a 100 x 37 output (`phases` 0: a windowable plan;
/// 5: flow), for the targets and the manifest's unit tests.
pub(crate) fn sample(phases: usize) -> Manifest {
    Manifest {
        format: FORMAT.into(),
        version: VERSION,
        command: if phases > 0 { "flow" } else { "refine" }.into(),
        args: vec![],
        job: serde_json::Value::Null,
        inputs: vec![],
        prepared: bytes_sum(b"", "input.tif".into()),
        output: OutputGrid {
            path: "/o.tif".into(),
            width: 100,
            height: 37,
            cell_size: [1.0, 1.0],
            georef: None,
        },
        tile: 32,
        tiles_x: 4,
        tiles_y: 2,
        tasks: 8,
        phases,
        plan_id: "ab".repeat(32),
    }
}

/// A tile record: an accepted one names its own tile's file and window.
pub fn tile_record(bytes: &[u8]) {
    let m = sample(0);
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
    let m = sample(5);
    for phase in 1..=5 {
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
