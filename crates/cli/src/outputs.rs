//! Output-path checks run by every command before it reads or computes anything: an output (or
//! a file it implies, such as the `.json` sidecar of an `.f32` raster) that is one of the
//! command's inputs (or a file an input implies) is refused, an output whose extension does not
//! match what the command writes is refused, and an existing file is only replaced under the
//! global `--force`. Together with the atomic writes of `relief-io` this means no command can
//! destroy data it was given.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

/// What a command writes at an output path; decides which extensions are accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum OutKind {
    /// A raster in any format relief-io writes (`.tif`, `.png`, `.exr`, `.npy`, `.r16`, ...).
    Raster,
    /// A raster or a `.sct` model (amplify, synthesize).
    RasterOrSct,
    /// A Sparse Construction Tree model (`.sct`).
    Sct,
    /// A learned dictionary (`.dict`).
    Dict,
    /// A PNG image (previews, renders, plots, seam maps).
    Png,
    /// A mesh (`.obj`, `.ply`, `.glb`).
    Mesh,
    /// A JSON document (`.json`, `.geojson`: reports, channel networks).
    Json,
    /// Headerless 16-bit samples for a game engine (`.raw`, `.r16`: `relief export`).
    Raw16,
    /// Plain text (`.txt`: the import sheet of `relief export`).
    Text,
}

fn ext_of(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default()
}

fn is_writable_raster(path: &Path) -> bool {
    use relief_io::Format;
    matches!(
        Format::from_extension(path),
        Some(
            Format::GeoTiff
                | Format::Hgt
                | Format::AsciiGrid
                | Format::Png
                | Format::Exr
                | Format::R16
                | Format::R32
                | Format::Npy
                | Format::F32Sidecar
        )
    )
}

const RASTER_EXTS: &str = ".tif, .asc, .png, .exr, .npy, .r16, .r32, .f32, .hgt";

/// Refuses `path` when its extension does not name what `kind` writes.
pub(crate) fn check_extension(path: &Path, kind: OutKind) -> Result<()> {
    let ext = ext_of(path);
    let ok = match kind {
        OutKind::Raster => is_writable_raster(path),
        OutKind::RasterOrSct => ext == "sct" || is_writable_raster(path),
        OutKind::Sct => ext == "sct",
        OutKind::Dict => ext == "dict",
        OutKind::Png => ext == "png",
        OutKind::Mesh => matches!(ext.as_str(), "obj" | "ply" | "glb"),
        OutKind::Json => matches!(ext.as_str(), "json" | "geojson"),
        OutKind::Raw16 => matches!(ext.as_str(), "raw" | "r16"),
        OutKind::Text => ext == "txt",
    };
    if ok {
        return Ok(());
    }
    let expected = match kind {
        OutKind::Raster => format!("a raster extension ({RASTER_EXTS})"),
        OutKind::RasterOrSct => format!(".sct or a raster extension ({RASTER_EXTS})"),
        OutKind::Sct => ".sct (this command writes a sparse construction tree)".into(),
        OutKind::Dict => ".dict (this command writes a dictionary)".into(),
        OutKind::Png => ".png (this command writes a PNG image)".into(),
        OutKind::Mesh => ".obj, .ply or .glb (this command writes a mesh)".into(),
        OutKind::Json => ".json or .geojson (this command writes JSON)".into(),
        OutKind::Raw16 => ".raw or .r16 (this command writes 16-bit raw samples)".into(),
        OutKind::Text => ".txt (this command writes text)".into(),
    };
    bail!("output {}: the name must end in {expected}", path.display())
}

/// The files written for an output: the path itself, plus the `.json` sidecar of an `.f32`
/// and the `.prj` of an ESRI ASCII grid.
/// (A raster writes the sidecar its reader reads: the files of [`read_files`].)
fn written_files(path: &Path, kind: OutKind) -> Vec<PathBuf> {
    if matches!(kind, OutKind::Raster | OutKind::RasterOrSct) {
        read_files(path)
    } else {
        vec![path.to_path_buf()]
    }
}

/// The files read for an input: the path itself, plus the `.json` sidecar of an `.f32`, the
/// `.prj` of an ESRI ASCII grid and the `FILE.png.json` / `FILE.r16.json` of a 16-bit
/// heightmap (its cell size and height mapping): an output may not replace any of them
/// (`convert h.png h.png.f32` would write its own sidecar over `h.png.json`).
fn read_files(path: &Path) -> Vec<PathBuf> {
    let mut v = vec![path.to_path_buf()];
    if ext_of(path) == "f32" {
        v.push(path.with_extension("json"));
    } else if matches!(ext_of(path).as_str(), "asc" | "grd") {
        v.push(path.with_extension("prj"));
    } else if relief_io::heightmap16::is_heightmap16(path) {
        v.push(relief_io::heightmap16::heightmap_sidecar(path));
    }
    v
}

/// The folder `path` is in (`.` for a bare file name).
pub(crate) fn parent_folder(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Whether two existing paths name the same file (same device and inode on Unix, same
/// canonical path elsewhere).
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return ma.dev() == mb.dev() && ma.ino() == mb.ino();
        }
        false
    }
    #[cfg(not(unix))]
    {
        match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
            (Ok(ca), Ok(cb)) => ca == cb,
            _ => false,
        }
    }
}

/// Lexical identity for paths that do not exist yet (two outputs naming the same new file).
fn same_name(a: &Path, b: &Path) -> bool {
    let abs = |p: &Path| {
        std::path::absolute(p)
            .unwrap_or_else(|_| p.to_path_buf())
            .components()
            .collect::<PathBuf>()
    };
    abs(a) == abs(b)
}

/// Whether `path` ends in `.ext` (ASCII case ignored).
pub(crate) fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

/// Refuses a `--<what>` image path that does not end in `.png`.
pub(crate) fn check_png_flag(p: Option<&Path>, what: &str) -> Result<()> {
    if let Some(p) = p
        && !has_extension(p, "png")
    {
        bail!("--{what} {}: the file must end in .png", p.display());
    }
    Ok(())
}

/// Refuses a `--report` path that is not `.json`, is the input, or exists without `--force`.
pub(crate) fn check_report_path(report: &Path, input: &Path, force: bool) -> Result<()> {
    if !has_extension(report, "json") {
        bail!("--report {}: the file must end in .json", report.display());
    }
    if report.exists() {
        let same = std::fs::canonicalize(report).ok() == std::fs::canonicalize(input).ok();
        if same {
            bail!("--report {}: is the input", report.display());
        }
        if !force {
            bail!(
                "--report {}: exists (use --force to overwrite)",
                report.display()
            );
        }
    }
    Ok(())
}

/// Checks every output of a command before it starts: extension matches `kind`, no output (or
/// implied sidecar) is an input or another output, and an existing file is only replaced when
/// `force` is set. `inputs` are every file the command reads.
pub(crate) fn check_outputs(
    inputs: &[&Path],
    outputs: &[(&Path, OutKind)],
    force: bool,
) -> Result<()> {
    let read: Vec<PathBuf> = inputs.iter().flat_map(|p| read_files(p)).collect();
    let mut planned: Vec<PathBuf> = Vec::new();
    for &(out, kind) in outputs {
        check_extension(out, kind)?;
        let folder = parent_folder(out);
        if !folder.is_dir() {
            bail!(
                "cannot write {}: {} {}",
                out.display(),
                folder.display(),
                if folder.exists() {
                    "is not a folder"
                } else {
                    "does not exist"
                }
            );
        }
        for file in written_files(out, kind) {
            if let Some(input) = read
                .iter()
                .find(|i| same_file(i, &file) || same_name(i, &file))
            {
                if file.as_path() == out {
                    bail!(
                        "output {} is the input {}: refusing to overwrite an input (choose \
                         another output name)",
                        out.display(),
                        input.display()
                    );
                }
                bail!(
                    "output {} would overwrite the input {} (its sidecar): choose another \
                     output name",
                    out.display(),
                    input.display()
                );
            }
            if planned.iter().any(|p| same_name(p, &file)) {
                bail!(
                    "{} is named as two outputs of the same command",
                    file.display()
                );
            }
            if let Ok(m) = std::fs::metadata(&file)
                && !m.is_file()
            {
                bail!(
                    "output {} exists and is not a regular file (a device, pipe, socket or \
                     folder): relief only writes regular files, --force or not",
                    file.display()
                );
            }
            if !force && file.exists() {
                bail!(
                    "{} already exists: pass --force to overwrite it",
                    file.display()
                );
            }
            if !force {
                // Checked absent: the write creates it exclusively, so another run that
                // creates the same name meanwhile makes this one fail instead of losing.
                relief_io::create_new_only(&file);
            }
            planned.push(file);
        }
    }
    // Hidden temporaries that killed runs left in the output folders go now, whatever output
    // they were for.
    for file in &planned {
        relief_io::remove_stale_temporaries(parent_folder(file));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touch(p: &Path) {
        std::fs::write(p, b"x").unwrap();
    }

    /// A one-byte file `name` in `dir`.
    fn touched(dir: &Path, name: &str) -> PathBuf {
        let p = dir.join(name);
        touch(&p);
        p
    }

    #[test]
    fn refuses_input_as_output_and_sidecar_of_input() {
        let d = tempfile::tempdir().unwrap();
        let inp = touched(d.path(), "volcano.json");
        // `convert volcano.json volcano.f32` would write volcano.json as the sidecar.
        let out = d.path().join("volcano.f32");
        let e = check_outputs(&[&inp], &[(&out, OutKind::Raster)], true).unwrap_err();
        assert!(e.to_string().contains("would overwrite the input"), "{e}");
        // Same file through another spelling, even with --force.
        let other = d.path().join(".").join("volcano.json");
        let e = check_outputs(&[&inp], &[(&other, OutKind::Raster)], true);
        assert!(e.is_err());
        let tif = touched(d.path(), "in.tif");
        let e = check_outputs(&[&tif], &[(&tif, OutKind::Raster)], true).unwrap_err();
        assert!(e.to_string().contains("is the input"), "{e}");
    }

    #[test]
    fn an_output_sidecar_over_an_input_sidecar_is_refused() {
        // Issue 44 item 9: `convert h.png h.png.f32` wrote h.png.f32's sidecar over
        // h.png.json, the input heightmap's own, under --force.
        let d = tempfile::tempdir().unwrap();
        let png = touched(d.path(), "h.png");
        let side = touched(d.path(), "h.png.json");
        let out = d.path().join("h.png.f32");
        let e = check_outputs(&[&png], &[(&out, OutKind::Raster)], true).unwrap_err();
        assert!(e.to_string().contains("would overwrite the input"), "{e}");
        // The sidecar itself named as an output, and an .r16's.
        assert!(check_outputs(&[&png], &[(&side, OutKind::Json)], true).is_err());
        let r16 = touched(d.path(), "h.r16");
        let out = d.path().join("h.r16.f32");
        assert!(check_outputs(&[&r16], &[(&out, OutKind::Raster)], true).is_err());
        // Another name is fine.
        let out = d.path().join("g.f32");
        assert!(check_outputs(&[&png], &[(&out, OutKind::Raster)], true).is_ok());
    }

    #[test]
    fn hard_link_to_input_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let inp = touched(d.path(), "a.tif");
        let link = d.path().join("b.tif");
        std::fs::hard_link(&inp, &link).unwrap();
        assert!(check_outputs(&[&inp], &[(&link, OutKind::Raster)], true).is_err());
    }

    #[test]
    fn existing_output_needs_force() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("o.tif");
        assert!(check_outputs(&[], &[(&out, OutKind::Raster)], false).is_ok());
        touch(&out);
        let e = check_outputs(&[], &[(&out, OutKind::Raster)], false).unwrap_err();
        assert!(e.to_string().contains("--force"), "{e}");
        assert!(check_outputs(&[], &[(&out, OutKind::Raster)], true).is_ok());
        // The sidecar an `.f32` output implies counts too.
        let f = d.path().join("x.f32");
        touch(&d.path().join("x.json"));
        assert!(check_outputs(&[], &[(&f, OutKind::Raster)], false).is_err());
    }

    #[test]
    fn extensions_match_the_kind() {
        let p = Path::new;
        assert!(check_extension(p("a.tif"), OutKind::Raster).is_ok());
        assert!(check_extension(p("a.sct"), OutKind::Raster).is_err());
        assert!(check_extension(p("a.npz"), OutKind::Raster).is_err());
        assert!(check_extension(p("a.json"), OutKind::Raster).is_err());
        assert!(check_extension(p("a.sct"), OutKind::RasterOrSct).is_ok());
        assert!(check_extension(p("a.tif"), OutKind::Dict).is_err());
        assert!(check_extension(p("a.DICT"), OutKind::Dict).is_ok());
        assert!(check_extension(p("a.tif"), OutKind::Sct).is_err());
        assert!(check_extension(p("p.tif"), OutKind::Png).is_err());
        assert!(check_extension(p("m.glb"), OutKind::Mesh).is_ok());
        assert!(check_extension(p("m.stl"), OutKind::Mesh).is_err());
    }

    #[test]
    fn devices_and_folders_are_refused_even_with_force() {
        let d = tempfile::tempdir().unwrap();
        let dir = d.path().join("x.tif");
        std::fs::create_dir(&dir).unwrap();
        let e = check_outputs(&[], &[(&dir, OutKind::Raster)], true).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        if Path::new("/dev/null").exists() {
            let e = check_outputs(&[], &[(Path::new("/dev/null"), OutKind::Raster)], true);
            assert!(e.is_err());
        }
    }

    #[test]
    fn two_outputs_with_one_name_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let a = d.path().join("r.png");
        let e = check_outputs(&[], &[(&a, OutKind::Png), (&a, OutKind::Png)], false);
        assert!(e.is_err());
    }
}
