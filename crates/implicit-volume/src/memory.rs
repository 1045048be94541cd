//! Working-memory model of a volume job, beside the algorithms it models: the pre-flight
//! estimates `relief volume` and the pipeline's `volume` stage check against `--max-memory`
//! before any work (calibrated on measured peak RSS).

/// Triangles per horizontal mesh cell assumed by the pre-flight estimate: a terrain surface
/// has 2; caves, arches, islands and overhangs add walls and ceilings. The default features on
/// a synthetic 128^2 DEM gave 22 (1.5 M triangles on a 262^2 grid; issue 18 measured 19 on its
/// case).
pub const TRIANGLES_PER_COLUMN: f64 = 24.0;

/// Peak bytes per triangle while meshing and writing: positions and normals of about half a
/// vertex (24 B), the triangle (12 B), the vertex map of the chunked polygoniser and the
/// encoded file built in memory before the atomic write (measured: 69-81 B at 1.5-6 M
/// triangles, release build).
pub const MESH_BYTES_PER_TRIANGLE: f64 = 90.0;

/// Bytes per file triangle (binary PLY/GLB: 12 B of indices plus half a vertex of 24 B).
pub const FILE_BYTES_PER_TRIANGLE: f64 = 26.0;

/// Bytes per pixel of the render and the section (RGB, depth, normals, per-ray state).
pub const IMAGE_BYTES_PER_PIXEL: f64 = 64.0;

/// The working memory of a volume job on a `w x h` DEM of `cell` metres, before the scene is
/// built (the pipeline's `volume` stage): the mesh of the polygonisation grid (one column per
/// voxel, the recipe's voxel or else the DEM's smaller cell side, at most `max_mesh_cells` a
/// side) and the images.
pub fn volume_job_bytes((w, h): (usize, usize), cell: (f64, f64), job: &crate::VolumeJob) -> f64 {
    let voxel = job
        .recipe
        .voxel
        .map_or(cell.0.min(cell.1), f64::from)
        .max(1e-6);
    let side = |n: usize, c: f64| (n as f64 * c / voxel).ceil().min(job.max_mesh_cells as f64);
    let columns = side(w, cell.0) * side(h, cell.1);
    let mesh = if job.mesh {
        columns * TRIANGLES_PER_COLUMN * MESH_BYTES_PER_TRIANGLE
    } else {
        0.0
    };
    let images = if job.render || job.section || job.closeups {
        (job.image_size[0] * job.image_size[1]) as f64 * IMAGE_BYTES_PER_PIXEL
    } else {
        0.0
    };
    mesh + images
}
