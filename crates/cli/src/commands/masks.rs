//! `relief masks DEM -o OUT_DIR`: texturing masks of a DEM with relief-landscape's
//! [`MasksSettings`]: slope, profile and plan curvature, log drainage area, wetness index,
//! height above the nearest drainage, height bands (and the erosion and deposition depths of an
//! erosion run, `--erosion-depth` / `--deposition-depth`), each written as a GeoTIFF in
//! physical units with the input's georeference, or as a PNG of the mask normalised to
//! `[0, 1]` (`--format png8|png16`); plus `splat.png`, four weights per cell in RGBA (ground,
//! rock, sediment, wet) summing to 1 (to 255 in every pixel), and `masks.json` (the settings,
//! the height bands and the files). Everything appears together or not at all.
//!
//! ```text
//! relief masks dem.tif -o masks
//! relief masks dem.tif -o masks --format png16 --rock-slope 40 --height-bands 1200,1800
//! ```

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use relief_heightfield::Progress;
use relief_landscape::flow::job::FlowSettings;
use relief_landscape::masks::{Mask, MaskKind, MasksSettings, splat_rgba8};
use serde::Serialize;

use crate::args::flag_error;
use crate::ctx::Ctx;
use crate::outputs::OutKind;

/// How the masks are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum MaskFormat {
    /// GeoTIFF (float32) in physical units, with the input's georeference.
    Tif,
    /// 8-bit grey PNG of the mask normalised to [0, 1].
    Png8,
    /// 16-bit grey PNG of the mask normalised to [0, 1] (count = value x 65535).
    Png16,
}

/// Arguments of `relief masks`: the [`MasksSettings`] fields as flags (its `flow` as the
/// flags of `relief flow`), defaults from `MasksSettings::default()`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input DEM (format detected from its content); voids stay voids (0 in PNGs and the
    /// splat map).
    pub(crate) input: PathBuf,
    /// Output folder (created when absent; its parent must exist): one file per mask, splat.png
    /// and masks.json.
    #[arg(short = 'o', long = "out", value_name = "OUT_DIR")]
    pub(crate) out: PathBuf,
    /// How each mask is written: tif (physical units), png8 or png16 (normalised to [0, 1]).
    #[arg(long, value_enum, default_value_t = MaskFormat::Tif)]
    pub(crate) format: MaskFormat,
    /// Upper limits of the height bands in metres, increasing, comma-separated (default: the
    /// DEM's quartiles).
    #[arg(
        long,
        value_name = "M,M,...",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub(crate) height_bands: Vec<f64>,
    /// Slope in degrees from which the splat map's rock layer (G) takes over.
    #[arg(long, value_name = "DEG", allow_hyphen_values = true, default_value_t = MasksSettings::default().rock_slope)]
    pub(crate) rock_slope: f64,
    /// Wetness index from which the splat map's wet layer (A) takes over.
    #[arg(long, value_name = "TWI", allow_hyphen_values = true, default_value_t = MasksSettings::default().wet_index)]
    pub(crate) wet_index: f64,
    /// Erosion depth raster (m, the DEM's grid; `relief erode --erosion`): adds the erosion
    /// mask.
    #[arg(long, value_name = "RASTER")]
    pub(crate) erosion_depth: Option<PathBuf>,
    /// Deposition depth raster (m, the DEM's grid; `relief erode --deposition`): adds the
    /// deposition mask and drives the splat map's sediment layer (B).
    #[arg(long, value_name = "RASTER")]
    pub(crate) deposition_depth: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) flow: super::flow::FlowArgs,
    /// Print masks.json instead of a summary.
    #[arg(long)]
    pub(crate) json: bool,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// The flags as checked [`MasksSettings`] (an error names the flag).
pub(crate) fn settings(args: &Args) -> Result<MasksSettings> {
    let s = MasksSettings {
        flow: args.flow.settings(),
        height_bands: args.height_bands.clone(),
        rock_slope: args.rock_slope,
        wet_index: args.wet_index,
    };
    s.check().map_err(flag_error)?;
    Ok(s)
}

/// The masks every run writes, in the library's order.
pub(crate) const BASE_KINDS: [MaskKind; 7] = [
    MaskKind::Slope,
    MaskKind::ProfileCurvature,
    MaskKind::PlanCurvature,
    MaskKind::Area,
    MaskKind::Wetness,
    MaskKind::Hand,
    MaskKind::HeightBand,
];

/// The masks a run writes, in the library's order.
fn kinds(args: &Args) -> Vec<MaskKind> {
    let mut v = BASE_KINDS.to_vec();
    v.extend(args.erosion_depth.as_ref().map(|_| MaskKind::Erosion));
    v.extend(args.deposition_depth.as_ref().map(|_| MaskKind::Deposition));
    v
}

pub(crate) fn file_name(kind: MaskKind, format: MaskFormat) -> String {
    match format {
        MaskFormat::Tif => format!("{}.tif", kind.name()),
        MaskFormat::Png8 | MaskFormat::Png16 => format!("{}.png", kind.name()),
    }
}

/// Working bytes per cell beside the routing's ([`FlowSettings::BYTES_PER_CELL`]): nine f32
/// masks (36), the splat weights (16), a normalised copy (4) and the RGBA map (4), the
/// encoding of one file (8).
const MASK_BYTES_PER_CELL: u64 = 68;

/// `masks.json` and what `--json` prints (and what the mosaic of a tiled masks plan writes).
#[derive(Debug, Serialize)]
pub(crate) struct Report {
    #[serde(flatten)]
    pub(crate) input: super::InputGrid,
    pub(crate) settings: MasksSettings,
    /// Upper limits of the height bands used (m).
    pub(crate) bands: Vec<f64>,
    pub(crate) format: &'static str,
    /// `(mask, file)`.
    pub(crate) masks: Vec<(MaskKind, String)>,
    pub(crate) splat: &'static str,
    pub(crate) splat_channels: [&'static str; 4],
}

/// The splat map's channels, in RGBA order.
pub(crate) const SPLAT_CHANNELS: [&str; 4] = ["ground", "rock", "sediment", "wet"];

/// Reads the DEM (and the erosion rasters), computes the masks, writes the folder.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let settings = settings(&args)?;
    let kinds = kinds(&args);
    let names: Vec<String> = kinds.iter().map(|&k| file_name(k, args.format)).collect();
    let kind_of = |f: MaskFormat| match f {
        MaskFormat::Tif => OutKind::Raster,
        _ => OutKind::Png,
    };
    let mut files: Vec<(&str, OutKind)> = names
        .iter()
        .map(|n| (n.as_str(), kind_of(args.format)))
        .collect();
    files.push(("splat.png", OutKind::Png));
    files.push(("masks.json", OutKind::Json));
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(args.erosion_depth.as_deref());
    inputs.extend(args.deposition_depth.as_deref());
    let staged = crate::folder::FolderOutputs::new(&args.out, &files, &inputs, ctx)?;
    let job = super::JobCells {
        command: "masks",
        what: "the masks",
        bytes_per_cell: FlowSettings::BYTES_PER_CELL + MASK_BYTES_PER_CELL,
        output_bytes_per_cell: kinds.len() as u64 * 4 + 4,
    };
    let dem = super::read_raster_for(&args.input, &args.read, ctx, Some(job))?.heightfield;
    let side =
        |p: &Option<PathBuf>, flag: &str| -> Result<Option<relief_heightfield::Heightfield>> {
            let Some(p) = p else {
                return Ok(None);
            };
            let r = super::read_raster(p, &super::ReadArgs::default(), ctx)?.heightfield;
            if (r.width(), r.height()) != (dem.width(), dem.height()) {
                bail!(
                    "--{flag} {} is {} x {}, the DEM {} x {}: they must match",
                    p.display(),
                    r.width(),
                    r.height(),
                    dem.width(),
                    dem.height()
                );
            }
            Ok(Some(r))
        };
    let (erosion, deposition) = (
        side(&args.erosion_depth, "erosion-depth")?,
        side(&args.deposition_depth, "deposition-depth")?,
    );
    if let Some((est, how)) =
        crate::budget::crop_pilot_seconds((dem.width(), dem.height()), |x, y, w, h| {
            let crop = |r: &relief_heightfield::Heightfield| r.crop(x, y, w, h);
            let (e, d) = (
                erosion.as_ref().map(crop).transpose()?,
                deposition.as_ref().map(crop).transpose()?,
            );
            // A crop of voids only has nothing to route: the pilot then times nothing.
            match settings.run(
                &crop(&dem)?,
                e.as_ref(),
                d.as_ref(),
                &relief_heightfield::NoProgress,
            ) {
                Ok(_) | Err(relief_landscape::LandscapeError::InvalidInput(_)) => Ok(()),
                Err(e) => Err(e.into()),
            }
        })?
    {
        ctx.check_time("the masks", est, &how, "a smaller input (crop it)")?;
    }
    let progress = ctx.progress();
    let masks = settings
        .run(&dem, erosion.as_ref(), deposition.as_ref(), &progress)
        .with_context(|| format!("cannot compute the masks of {}", args.input.display()))?;
    progress.begin("writing", 0);
    let (w, h) = (dem.width(), dem.height());
    let mut written = Vec::new();
    for (kind, raster) in &masks.rasters {
        let Some(k) = kinds.iter().position(|x| x == kind) else {
            bail!("the library made an unplanned mask `{}`", kind.name());
        };
        let name = &names[k];
        let path = staged.path(name);
        match args.format {
            MaskFormat::Tif => ctx.write_raster(&path, raster)?,
            MaskFormat::Png8 => {
                let v = Mask::normalised(*kind, raster.as_slice(), masks.bands.len());
                let grey: Vec<u8> = v.iter().map(|x| (x * 255.0).round() as u8).collect();
                relief_io::write_gray_png(&path, w, h, &grey)
                    .with_context(|| format!("cannot write {}", staged.target(name).display()))?;
            }
            MaskFormat::Png16 => {
                let v = Mask::normalised(*kind, raster.as_slice(), masks.bands.len());
                let hf = raster.with_data(v)?;
                let opts = relief_io::WriteOptions {
                    mapping: Some((0.0, 1.0 / 65535.0)),
                    ..ctx.write_options()
                };
                relief_io::write(&path, &hf, &opts)
                    .with_context(|| format!("cannot write {}", staged.target(name).display()))?;
            }
        }
        written.push((*kind, name.clone()));
    }
    let rgba = splat_rgba8(&masks.splat);
    relief_io::write_rgba_png(&staged.path("splat.png"), w, h, &rgba)
        .with_context(|| format!("cannot write {}", staged.target("splat.png").display()))?;
    let report = Report {
        input: super::InputGrid::of(&args.input, &dem),
        settings,
        bands: masks.bands.clone(),
        format: match args.format {
            MaskFormat::Tif => "tif",
            MaskFormat::Png8 => "png8",
            MaskFormat::Png16 => "png16",
        },
        masks: written,
        splat: "splat.png",
        splat_channels: SPLAT_CHANNELS,
    };
    staged.write_json("masks.json", &report, true)?;
    crate::budget::commit_in_time("masks", progress, || staged.commit())?;
    let text = if args.json {
        crate::staging::json_text(&report)?
    } else {
        let list: Vec<&str> = report.masks.iter().map(|(_, f)| f.as_str()).collect();
        format!(
            "file:   {}\nsize:   {w} x {h}\nbands:  {:?} m\nwrote:  {}/{{{},splat.png,masks.json}}\n",
            report.input.file,
            report.bands,
            args.out.display(),
            list.join(",")
        )
    };
    crate::staging::print(&text)
}
