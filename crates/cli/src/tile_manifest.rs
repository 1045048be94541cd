//! The tile plan format of `relief tile` (`DIR/manifest.json`, `DIR/tiles/tile-N.json`):
//! the manifest, its checksums (SHA-256) and plan id, the tile grid, the state of a tile and
//! the GDAL VRT over the tiles.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use relief_heightfield::{GeoRef, Heightfield};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// `DIR/manifest.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Manifest {
    /// Always `relief-tile-plan`.
    pub(crate) format: String,
    pub(crate) version: u32,
    /// Subcommand (`amplify`, `refine`, `decompress`).
    pub(crate) command: String,
    /// Subcommand and arguments as planned, paths absolute.
    pub(crate) args: Vec<String>,
    /// The job's settings as the method crate defines them (serde): `RefineSettings` for
    /// refine, `AmplifySettings` for amplify (the model is prepared), `{"scale": s}` for
    /// decompress. Tasks run from these, not from re-parsed flags.
    pub(crate) job: serde_json::Value,
    /// The command's input files at plan time.
    pub(crate) inputs: Vec<FileSum>,
    /// The file in DIR every task reads (path relative to DIR).
    pub(crate) prepared: FileSum,
    /// The planned output.
    pub(crate) output: OutputGrid,
    /// Tile side and the tile grid.
    pub(crate) tile: usize,
    pub(crate) tiles_x: usize,
    pub(crate) tiles_y: usize,
    /// Number of tasks (one per tile, row-major from the north-west tile).
    pub(crate) tasks: usize,
    /// Phases of a multi-phase plan (`flow`: 5, each one task per tile or one task); absent
    /// (0) for the one-phase plans of the windowable commands, whose plan ids it leaves as
    /// they were.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub(crate) phases: usize,
    /// SHA-256 of the plan (every field above), recorded by every tile.
    pub(crate) plan_id: String,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub(crate) struct FileSum {
    pub(crate) path: String,
    pub(crate) bytes: u64,
    pub(crate) sha256: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct OutputGrid {
    pub(crate) path: String,
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) cell_size: [f64; 2],
    pub(crate) georef: Option<GeoRef>,
}

/// `DIR/tiles/tile-NNNNNN.json`: a tile that is complete.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub(crate) struct TileRecord {
    pub(crate) plan_id: String,
    pub(crate) index: usize,
    pub(crate) window: [usize; 4],
    pub(crate) file: FileSum,
}

pub(crate) const MANIFEST: &str = "manifest.json";
pub(crate) const FORMAT: &str = "relief-tile-plan";

/// Manifest version (2: the job's settings are stored in `job`).
pub(crate) const VERSION: u32 = 2;
/// Rows of the output decoded at once by the mosaic (a 32768-wide output: 8 MiB).
pub(crate) const MOSAIC_ROWS: usize = 64;
/// Largest tile grid a plan accepts.
pub(crate) const MAX_TASKS: usize = 1 << 20;
/// Scheduler variables holding the task index, in the order they are consulted.
pub(crate) const INDEX_VARS: [&str; 3] = [
    "SLURM_ARRAY_TASK_ID",
    "JOB_COMPLETION_INDEX",
    "AWS_BATCH_JOB_ARRAY_INDEX",
];

fn is_zero(v: &usize) -> bool {
    *v == 0
}

pub(crate) fn hex(d: impl AsRef<[u8]>) -> String {
    d.as_ref().iter().map(|b| format!("{b:02x}")).collect()
}

/// Checksum of a file, streamed.
pub(crate) fn file_sum(path: &Path, name: String) -> Result<FileSum> {
    use std::io::Read;
    let mut f =
        std::fs::File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = f
            .read(&mut buf)
            .with_context(|| format!("cannot read {}", path.display()))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
        bytes += n as u64;
    }
    Ok(FileSum {
        path: name,
        bytes,
        sha256: hex(h.finalize()),
    })
}

pub(crate) fn bytes_sum(bytes: &[u8], name: String) -> FileSum {
    FileSum {
        path: name,
        bytes: bytes.len() as u64,
        sha256: hex(Sha256::digest(bytes)),
    }
}

/// Largest manifest a plan folder may hold (a plan of [`MAX_TASKS`] tasks stays far below:
/// the manifest does not list the tasks).
pub(crate) const MAX_MANIFEST_BYTES: u64 = 16 << 20;
/// Largest tile record (a few hundred bytes are written).
pub(crate) const MAX_RECORD_BYTES: u64 = 64 << 10;
/// Largest side of a planned output (2^24 cells: 256 Ti cells in all).
pub(crate) const MAX_SIDE: usize = 1 << 24;

/// Whether `name` is a path inside the plan folder: relative, only plain components (no `..`,
/// no root, no prefix), not empty.
pub(crate) fn is_inside_name(name: &str) -> bool {
    use std::path::Component;
    let p = Path::new(name);
    !name.is_empty()
        && !name.contains('\\')
        && p.components().all(|c| matches!(c, Component::Normal(_)))
}

/// Reads a plan file by its name relative to the plan folder: a regular file (not a link, a
/// device or a pipe) inside it, at most `max` bytes (checked before reading, and again while
/// reading, so a file that grows cannot hold the task).
pub(crate) fn read_plan_file(dir: &Path, name: &str, max: u64) -> Result<Vec<u8>> {
    use std::io::Read as _;
    if !is_inside_name(name) {
        bail!(
            "`{name}` is not a file name inside the plan folder {}",
            dir.display()
        );
    }
    let path = dir.join(name);
    let meta = std::fs::symlink_metadata(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    if !meta.file_type().is_file() {
        bail!(
            "{} is not a regular file (a link, a folder or a device): refusing to read it",
            path.display()
        );
    }
    if meta.len() > max {
        bail!(
            "{} holds {} bytes, more than the {max} it may hold",
            path.display(),
            meta.len()
        );
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::fs::File::open(&path)
        .with_context(|| format!("cannot read {}", path.display()))?
        .take(max + 1)
        .read_to_end(&mut bytes)
        .with_context(|| format!("cannot read {}", path.display()))?;
    if bytes.len() as u64 > max {
        bail!("{} grew beyond {max} bytes while read", path.display());
    }
    Ok(bytes)
}

/// The plan's folder `name` must be a real folder inside it: a link planted in place of one
/// would send a task's reads and writes outside the plan folder.
pub(crate) fn check_plan_folder(dir: &Path, name: &str) -> Result<()> {
    let p = dir.join(name);
    let meta = std::fs::symlink_metadata(&p)
        .with_context(|| format!("cannot read {} (is this a plan folder?)", p.display()))?;
    if !meta.file_type().is_dir() {
        bail!(
            "{} is not a folder of the plan (a link or a file): refusing to read or write \
             through it",
            p.display()
        );
    }
    Ok(())
}

/// Whether the plan's manifest can only have been written by the user running this command:
/// the manifest and the plan folder are owned by this user and writable by no one else (the
/// test `ssh` applies to its keys). Only then are the paths outside the plan folder that the
/// manifest names (the planned output, the inputs) followed; a plan in a folder others can
/// write (a shared NFS folder) may have been rewritten, plan id and all, since SHA-256 is not
/// keyed. Not Linux: never.
pub(crate) fn manifest_is_trusted(dir: &Path) -> bool {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::MetadataExt as _;
        let Ok(me) = std::fs::metadata("/proc/self") else {
            return false;
        };
        let private = |p: &Path| {
            std::fs::symlink_metadata(p).is_ok_and(|m| m.uid() == me.uid() && m.mode() & 0o022 == 0)
        };
        private(dir) && private(&dir.join(MANIFEST))
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = dir;
        false
    }
}

/// Where the mosaic writes: `given` (the user named it), else the planned output when the
/// manifest is trusted ([`manifest_is_trusted`]).
pub(crate) fn mosaic_output(dir: &Path, m: &Manifest, given: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = given {
        return Ok(p.to_path_buf());
    }
    if manifest_is_trusted(dir) {
        return Ok(PathBuf::from(&m.output.path));
    }
    bail!(
        "the plan folder {} or its manifest can be written by other users (or is not yours), \
         so the output path its manifest names is not followed: name the output with --out \
         (planned: {})",
        dir.display(),
        m.output.path
    )
}

/// Reads and checks `DIR/manifest.json`: a regular file of at most [`MAX_MANIFEST_BYTES`],
/// unmodified since planning, with a consistent tile grid of at most [`MAX_TASKS`] tasks and
/// a prepared file named inside the plan folder.
pub(crate) fn load_manifest(dir: &Path) -> Result<Manifest> {
    let path = dir.join(MANIFEST);
    let bytes = read_plan_file(dir, MANIFEST, MAX_MANIFEST_BYTES)
        .with_context(|| format!("cannot read {} (is this a plan folder?)", path.display()))?;
    parse_manifest(&bytes, &path)
}

/// Parses and checks the bytes of the manifest `path` (see [`load_manifest`]).
pub(crate) fn parse_manifest(bytes: &[u8], path: &Path) -> Result<Manifest> {
    let mut m: Manifest = serde_json::from_slice(bytes)
        .with_context(|| format!("{} is not a tile plan manifest", path.display()))?;
    if m.format != FORMAT || m.version != VERSION {
        bail!(
            "{} is not a version-{VERSION} {FORMAT} manifest (plan again with this relief)",
            path.display()
        );
    }
    let id = std::mem::take(&mut m.plan_id);
    let want = hex(Sha256::digest(serde_json::to_vec(&m)?));
    if id != want {
        bail!(
            "{} was modified after planning (its plan_id does not match its content)",
            path.display()
        );
    }
    m.plan_id = id;
    if m.tasks > MAX_TASKS
        || !(1..=MAX_SIDE).contains(&m.output.width)
        || !(1..=MAX_SIDE).contains(&m.output.height)
    {
        bail!(
            "{} plans {} tasks over a {} x {} output: more than a plan may hold ({MAX_TASKS} \
             tasks, {MAX_SIDE} cells a side)",
            path.display(),
            m.tasks,
            m.output.width,
            m.output.height
        );
    }
    if m.tile == 0
        || m.tiles_x != m.output.width.div_ceil(m.tile)
        || m.tiles_y != m.output.height.div_ceil(m.tile)
        || Some(m.tasks) != m.tiles_x.checked_mul(m.tiles_y)
    {
        bail!("{} has an inconsistent tile grid", path.display());
    }
    if !is_inside_name(&m.prepared.path) {
        bail!(
            "{} names its prepared file `{}` outside the plan folder",
            path.display(),
            m.prepared.path
        );
    }
    Ok(m)
}

impl Manifest {
    /// Output window `[x, y, w, h]` of task `i`.
    pub(crate) fn window(&self, i: usize) -> [usize; 4] {
        let (c, r) = (i % self.tiles_x, i / self.tiles_x);
        let (x, y) = (c * self.tile, r * self.tile);
        [
            x,
            y,
            self.tile.min(self.output.width - x),
            self.tile.min(self.output.height - y),
        ]
    }
}

/// `hf` as a DEFLATE GeoTIFF in memory (tiles and the planned refine input).
pub(crate) fn deflate_geotiff(hf: &Heightfield) -> Result<Vec<u8>> {
    let options = relief_io::WriteOptions {
        compression: relief_io::TiffCompression::Deflate,
        ..Default::default()
    };
    Ok(relief_io::encode(hf, relief_io::Format::GeoTiff, &options)?)
}

pub(crate) fn tile_name(i: usize) -> String {
    format!("tile-{i:06}.tif")
}

pub(crate) fn record_path(dir: &Path, i: usize) -> PathBuf {
    dir.join("tiles").join(format!("tile-{i:06}.json"))
}

/// State of one tile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum TileState {
    Done,
    Missing,
    /// A record whose tile file is absent, altered, or from another plan.
    Corrupt,
}

/// The state of tile `i`: its record (a regular file of at most [`MAX_RECORD_BYTES`] at its
/// fixed name) must be of this plan, this index and window, and name the tile's own file
/// (`tiles/tile-i.tif`: a record cannot point at another tile's file), a regular file with
/// the recorded length and checksum.
pub(crate) fn tile_state(dir: &Path, m: &Manifest, i: usize) -> TileState {
    let rec = format!("tiles/tile-{i:06}.json");
    if std::fs::symlink_metadata(dir.join(&rec)).is_err() {
        return TileState::Missing;
    }
    let Ok(bytes) = read_plan_file(dir, &rec, MAX_RECORD_BYTES) else {
        return TileState::Corrupt;
    };
    let Some(r) = parse_record(m, i, &bytes) else {
        return TileState::Corrupt;
    };
    let tile = dir.join("tiles").join(&r.file.path);
    let regular = std::fs::symlink_metadata(&tile)
        .is_ok_and(|md| md.file_type().is_file() && md.len() == r.file.bytes);
    if !regular {
        return TileState::Corrupt;
    }
    match file_sum(&tile, r.file.path.clone()) {
        Ok(s) if s == r.file => TileState::Done,
        _ => TileState::Corrupt,
    }
}

/// The record of tile `i` in `bytes` when it is one of this plan's, for this index and window,
/// naming the tile's own file.
pub(crate) fn parse_record(m: &Manifest, i: usize, bytes: &[u8]) -> Option<TileRecord> {
    let r = serde_json::from_slice::<TileRecord>(bytes).ok()?;
    let ok = r.plan_id == m.plan_id
        && r.index == i
        && i < m.tasks
        && r.window == m.window(i)
        && r.file.path == tile_name(i);
    ok.then_some(r)
}

/// A GDAL VRT over the tiles (paths relative to the VRT).
pub(crate) fn write_vrt(path: &Path, m: &Manifest) -> Result<()> {
    write_vrt_named(path, m, &|i| format!("tiles/{}", tile_name(i)))
}

/// A GDAL VRT over the tiles `name(i)` (paths relative to the plan folder, where the VRT is).
pub(crate) fn write_vrt_named(
    path: &Path,
    m: &Manifest,
    name: &dyn Fn(usize) -> String,
) -> Result<()> {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<VRTDataset rasterXSize=\"{}\" rasterYSize=\"{}\">",
        m.output.width, m.output.height
    );
    let g = m.output.georef.as_ref();
    if let Some(crs) = g
        .and_then(|g| g.crs.as_deref())
        .filter(|c| c.starts_with("EPSG:"))
    {
        let _ = writeln!(s, "  <SRS dataAxisToSRSAxisMapping=\"1,2\">{crs}</SRS>");
    }
    let t = g.and_then(|g| g.geotransform).unwrap_or([
        0.0,
        m.output.cell_size[0],
        0.0,
        0.0,
        0.0,
        -m.output.cell_size[1],
    ]);
    let _ = writeln!(
        s,
        "  <GeoTransform>{:e}, {:e}, {:e}, {:e}, {:e}, {:e}</GeoTransform>",
        t[0], t[1], t[2], t[3], t[4], t[5]
    );
    s.push_str("  <VRTRasterBand dataType=\"Float32\" band=\"1\">\n");
    for i in 0..m.tasks {
        let [x, y, w, h] = m.window(i);
        let _ = write!(
            s,
            "    <SimpleSource>\n      <SourceFilename relativeToVRT=\"1\">{}</SourceFilename>\n      \
             <SourceBand>1</SourceBand>\n      <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"{w}\" ySize=\"{h}\"/>\n      \
             <DstRect xOff=\"{x}\" yOff=\"{y}\" xSize=\"{w}\" ySize=\"{h}\"/>\n    </SimpleSource>\n",
            name(i)
        );
    }
    s.push_str("  </VRTRasterBand>\n</VRTDataset>\n");
    relief_io::write_bytes_atomic(path, s.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_cover_the_output_once() {
        let m = sample(0);
        let mut seen = vec![0u8; 100 * 37];
        for i in 0..m.tasks {
            let [x, y, w, h] = m.window(i);
            for yy in y..y + h {
                for xx in x..x + w {
                    seen[yy * 100 + xx] += 1;
                }
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
    }

    /// The plan id survives the manifest's JSON round trip: georeferences with awkward
    /// floats (a x64 cell of a Web-Mercator grid) read back to the same bits.
    #[test]
    fn manifests_round_trip_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let cell = 76.437_028_285_174_16 / 64.0;
        let mut m = Manifest {
            format: FORMAT.into(),
            version: VERSION,
            command: "refine".into(),
            args: vec!["refine".into()],
            job: serde_json::json!({"extra_levels": 2}),
            inputs: vec![],
            prepared: bytes_sum(b"abc", "input.tif".into()),
            output: OutputGrid {
                path: "/o.tif".into(),
                width: 32768,
                height: 32768,
                cell_size: [cell, cell * (1.0 + 1e-13)],
                georef: Some(GeoRef {
                    geotransform: Some([
                        -12_601_714.231_207_296,
                        cell,
                        0.0,
                        4_344_069.191_503_135_5,
                        0.0,
                        -cell,
                    ]),
                    crs: Some("EPSG:3857".into()),
                    ..Default::default()
                }),
            },
            tile: 4096,
            tiles_x: 8,
            tiles_y: 8,
            tasks: 64,
            phases: 0,
            plan_id: String::new(),
        };
        m.plan_id = hex(Sha256::digest(serde_json::to_vec(&m).unwrap()));
        let json = serde_json::to_string_pretty(&m).unwrap();
        std::fs::write(dir.path().join(MANIFEST), json).unwrap();
        let back = load_manifest(dir.path()).unwrap();
        assert_eq!(back.output.cell_size, m.output.cell_size);
        assert_eq!(back.plan_id, m.plan_id);
        std::fs::write(
            dir.path().join(MANIFEST),
            serde_json::to_string_pretty(&m)
                .unwrap()
                .replace("32768", "32769"),
        )
        .unwrap();
        assert!(load_manifest(dir.path()).is_err());
    }
}
