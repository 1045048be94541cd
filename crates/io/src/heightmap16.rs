//! relief's 16-bit heightmaps (PNG16, `.r16`) and the JSON sidecar beside them
//! (`FILE.png.json`, `FILE.r16.json`) that states what the format cannot: the size, the cell
//! size and the vertical mapping `height = offset_m + count * metres_per_count`.

use std::path::{Path, PathBuf};

use relief_heightfield::Heightfield;

/// The file beside a 16-bit heightmap that states its vertical mapping (`OUT.png.json`).
pub fn heightmap_sidecar(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".json");
    PathBuf::from(s)
}

/// Whether `path` is written as a 16-bit engine heightmap (PNG16 or `.r16`).
pub fn is_heightmap16(path: &Path) -> bool {
    matches!(
        crate::Format::from_extension(path),
        Some(crate::Format::Png | crate::Format::R16)
    )
}

/// What relief's `FILE.png.json` / `FILE.r16.json` sidecar beside a 16-bit heightmap states:
/// its size, its cell size (fields `cell_size_x_m`/`cell_size_y_m`, or `cell_size_m` as a
/// number or `[x, y]`) and its vertical mapping `height = offset_m + count * metres_per_count`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightmapSidecar {
    /// `width`, `height` of the heightmap.
    pub size: (u64, u64),
    /// Cell size in metres, when stated, positive and finite.
    pub cell: Option<(f64, f64)>,
    /// `(offset_m, metres_per_count)`, when stated and finite (the scale non-zero).
    pub mapping: Option<(f64, f64)>,
}

/// The sidecar of the 16-bit heightmap `path` (see [`HeightmapSidecar`]), when `path` is one
/// and the sidecar is a readable JSON object of at most 1 MiB stating `width` and `height`.
pub fn heightmap_sidecar_of(path: &Path) -> Option<HeightmapSidecar> {
    if !is_heightmap16(path) {
        return None;
    }
    let side = heightmap_sidecar(path);
    if !std::fs::metadata(&side).is_ok_and(|m| m.is_file() && m.len() <= 1 << 20) {
        return None;
    }
    let text = std::fs::read(side).ok()?;
    let v: serde_json::Value = serde_json::from_slice(&text).ok()?;
    let dim = |k: &str| v.get(k).and_then(serde_json::Value::as_u64);
    let size = (dim("width")?, dim("height")?);
    let num = |k: &str| v.get(k).and_then(serde_json::Value::as_f64);
    let both = v.get("cell_size_m").and_then(|c| match c {
        serde_json::Value::Array(a) if a.len() == 2 => Some((a[0].as_f64()?, a[1].as_f64()?)),
        c => c.as_f64().map(|x| (x, x)),
    });
    let cell = match (num("cell_size_x_m"), num("cell_size_y_m")) {
        (Some(x), Some(y)) => Some((x, y)),
        _ => both,
    }
    .filter(|c| c.0.is_finite() && c.1.is_finite() && c.0 > 0.0 && c.1 > 0.0);
    let mapping = match (num("offset_m"), num("metres_per_count")) {
        (Some(o), Some(k)) if o.is_finite() && k.is_finite() && k != 0.0 => Some((o, k)),
        _ => None,
    };
    Some(HeightmapSidecar {
        size,
        cell,
        mapping,
    })
}

/// The cell size stated by the sidecar of the 16-bit heightmap `path` ([`heightmap_sidecar_of`])
/// when its `width`/`height` match `hf`. These formats store no cell size of their own.
pub fn heightmap_sidecar_cell(path: &Path, hf: &Heightfield) -> Option<(f64, f64)> {
    let side = heightmap_sidecar_of(path)?;
    (side.size == (hf.width() as u64, hf.height() as u64))
        .then_some(side.cell)
        .flatten()
}

/// Whether a raster read from `path` came with a cell size of its own: formats that store one,
/// or a 16-bit heightmap with relief's sidecar. PNG, Terrain-RGB, EXR, raw and NPY files
/// otherwise get 1 m cells from the reader.
pub fn cell_size_stored(path: &Path, raster: &crate::Raster) -> bool {
    use crate::Format;
    !matches!(
        raster.format,
        Format::Png | Format::TerrainRgb | Format::Exr | Format::R16 | Format::R32 | Format::Npy
    ) || heightmap_sidecar_cell(path, &raster.heightfield).is_some()
}
