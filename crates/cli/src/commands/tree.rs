//! `relief tree build TREE.json OUT.sct`: a construction tree authored in JSON (guerin2016
//! section 5.4, [`relief_sparse_core::TreeSpec`]): layers from `.sct` files or DEMs compressed
//! with the default `compress` settings, operators, regions and rivers; `relief decompress`
//! rasterises the result at any scale or window.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use relief_dictionary_learning::CompressSettings;
use relief_sparse_core::{Sct, SparseError, TreeSpec};

use crate::ctx::Ctx;
use crate::sparse_model::{read_model_bytes, registry};

/// Arguments of `relief tree`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(subcommand)]
    command: TreeCommand,
}

#[derive(Debug, clap::Subcommand)]
enum TreeCommand {
    /// Build a .sct from a JSON tree: `{"root": NODE}` with NODE one of `{"layer": "FILE"}`
    /// (a .sct, or a DEM compressed with the default settings; paths relative to the JSON),
    /// `{"constant": Z}`, `{"blend"|"add"|"max"|"min": [NODE, ...]}`, `{"replace": {"base",
    /// "overlay", "region": {"rect": [X0,Y0,X1,Y1]} | {"disk": [CX,CY,R]}, "falloff"}}`,
    /// `{"river": {"path", "half_width", "depth", "bed"?}}` and `{"river_valley": {"on",
    /// "path", "valley_half_width", "bank_height", "channel_half_width"?, "channel_depth",
    /// "floor"?}}` (the paper's river sub-tree); coordinates in terrain cells of the first
    /// layer's grid (or `width`, `height`, `cell_size`).
    Build(BuildArgs),
}

/// Arguments of `relief tree build`.
#[derive(Debug, clap::Args)]
struct BuildArgs {
    /// The tree (JSON).
    spec: PathBuf,
    /// Output model (.sct).
    output: PathBuf,
    #[command(flatten)]
    read: super::ReadArgs,
}

/// Largest tree description read.
const MAX_SPEC_BYTES: u64 = 64 << 20;

/// Runs `relief tree`.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    match args.command {
        TreeCommand::Build(a) => build(a, ctx),
    }
}

fn build(args: BuildArgs, ctx: &Ctx) -> Result<()> {
    let len = std::fs::metadata(&args.spec)
        .with_context(|| format!("cannot read {}", args.spec.display()))?
        .len();
    if len > MAX_SPEC_BYTES {
        bail!(
            "{}: {len} bytes, above the {MAX_SPEC_BYTES} a tree description may take",
            args.spec.display()
        );
    }
    let text = std::fs::read_to_string(&args.spec)
        .with_context(|| format!("cannot read {}", args.spec.display()))?;
    let spec: TreeSpec = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a tree description", args.spec.display()))?;
    let dir = args.spec.parent().unwrap_or(Path::new(".")).to_path_buf();
    let layers: Vec<PathBuf> = spec.layers().iter().map(|l| dir.join(l)).collect();
    let mut inputs: Vec<&Path> = vec![args.spec.as_path()];
    inputs.extend(layers.iter().map(PathBuf::as_path));
    ctx.check_outputs(&inputs, &[(&args.output, crate::outputs::OutKind::Sct)])?;
    let mut failure: Option<anyhow::Error> = None;
    let mut compressed = 0usize;
    let sct = spec.build(&mut |name| {
        let path = dir.join(name);
        layer(&path, &args.read, ctx, &mut compressed).map_err(|e| {
            let msg = format!("layer {}", path.display());
            failure = Some(e.context(msg));
            SparseError::param("layer", name, "cannot be read")
        })
    });
    let sct = match (sct, failure) {
        (_, Some(e)) => return Err(e),
        (r, None) => r.with_context(|| format!("invalid tree {}", args.spec.display()))?,
    };
    let bytes = sct.to_bytes().context("cannot encode the tree")?;
    relief_io::write_bytes_atomic(&args.output, &bytes)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    #[allow(clippy::print_stdout)]
    {
        println!(
            "tree:   {} layer(s) ({compressed} compressed from DEMs), grid {} x {} of {} x {} m",
            layers.len(),
            sct.width(),
            sct.height(),
            sct.cell_size().0,
            sct.cell_size().1
        );
        println!("wrote:  {} ({} bytes)", args.output.display(), bytes.len());
    }
    Ok(())
}

/// A layer: a `.sct` read as it is, any other file read as a DEM and compressed.
fn layer(path: &Path, read: &super::ReadArgs, ctx: &Ctx, compressed: &mut usize) -> Result<Sct> {
    if crate::sparse_model::is_sct(path) {
        let bytes = read_model_bytes(path, ctx)?;
        return Sct::from_bytes(&bytes, &registry()).context("not a readable .sct");
    }
    let hf = super::read_raster(path, read, ctx)?.heightfield;
    if hf.has_voids() {
        bail!(
            "{} void cells: pass --fill-voids to fill them first",
            hf.void_count()
        );
    }
    let progress = ctx.progress();
    let out = CompressSettings::default()
        .run(&hf, None, &progress)
        .context("cannot compress it")?;
    *compressed += 1;
    Ok(out.sct)
}
