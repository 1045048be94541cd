//! Pipeline specs: which stages run, in which order, with which parameters.
//!
//! A spec is a JSON file (`cargo xtask pipeline SPEC.json`; an annotated example is
//! `docs/pipeline-spec.example.json`):
//!
//! ```json
//! {
//!   "input": "fixtures/grandcanyon.tif",
//!   "crop": [0, 0, 256, 256],
//!   "seed": 7,
//!   "stages": [
//!     { "stage": "load" },
//!     { "stage": "fill_voids" },
//!     { "stage": "convert" }
//!   ]
//! }
//! ```
//!
//! Every field but `stages` is optional (command-line flags and the default run fill them).
//! `params` is a JSON object whose fields are the stage's parameter struct (serde, missing
//! fields take the stage's defaults, unknown fields are an error). Stages compose: each starts
//! from the terrain the previous one produced.
//!
//! # Registering a stage
//! Add one entry to `REGISTRY`: its name and how it is built (`with_params::<YourParams>` for a
//! stage with parameters, whose parameter struct implements [`Stage`] and `StageParams`;
//! `|p| no_params(p, Box::new(YourStage))` for one without), at its place in the default run
//! ([`default_spec`]). The test below checks that every name builds.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::{
    PipelineConfig, Stage, convert, dictionary, erode, fill, flow, load, quilt, sparse, volume,
    wavelet,
};

/// One entry of a spec's `stages` list.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    /// Stage name (one of [`stage_names`]).
    pub stage: String,
    /// The stage's parameters (an object; `null` or absent = defaults).
    #[serde(default)]
    pub params: serde_json::Value,
}

impl StageSpec {
    /// A stage with default parameters.
    pub fn named(stage: &str) -> Self {
        Self {
            stage: stage.to_string(),
            params: serde_json::Value::Null,
        }
    }
}

/// A whole pipeline spec file.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PipelineSpec {
    /// Input DEM; a relative path is resolved against the spec file's folder (see
    /// [`PipelineConfig::resolve`]).
    #[serde(default)]
    pub input: Option<PathBuf>,
    /// Crop `[x, y, w, h]` applied by `load`.
    #[serde(default)]
    pub crop: Option<[usize; 4]>,
    /// Seed of every stochastic stage.
    #[serde(default)]
    pub seed: Option<u64>,
    /// The stages, in order (the first is normally `load`).
    pub stages: Vec<StageSpec>,
    /// The folder of the spec file (set by [`PipelineSpec::read`]).
    #[serde(skip)]
    pub base_dir: Option<PathBuf>,
}

/// Largest pipeline spec file read (a spec is a few kilobytes of JSON).
pub const MAX_SPEC_BYTES: u64 = 4 << 20;

impl PipelineSpec {
    /// Reads and checks a spec file: JSON syntax, field names, and that every stage builds.
    pub fn read(path: &Path) -> Result<Self> {
        use std::io::Read as _;
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|f| f.take(MAX_SPEC_BYTES + 1).read_to_end(&mut bytes))
            .with_context(|| format!("cannot read pipeline spec {}", path.display()))?;
        if bytes.len() as u64 > MAX_SPEC_BYTES {
            bail!(
                "{}: more than the {MAX_SPEC_BYTES} bytes a pipeline spec may take",
                path.display()
            );
        }
        Self::from_bytes(&bytes, path)
    }

    /// Parses and checks the bytes of the spec file `path` (see [`PipelineSpec::read`]).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self> {
        let mut spec: PipelineSpec = serde_json::from_slice(bytes)
            .with_context(|| format!("{} is not a valid pipeline spec", path.display()))?;
        if spec.stages.is_empty() {
            bail!("{}: `stages` is empty", path.display());
        }
        build_stages(&spec.stages).with_context(|| format!("in {}", path.display()))?;
        let base_dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        spec.base_dir = Some(base_dir);
        Ok(spec)
    }

    /// Applies the spec's optional fields to `config`.
    /// Relative paths (the input, stage files) are resolved against the spec's folder.
    pub fn apply(&self, config: &mut PipelineConfig) {
        if let Some(base) = &self.base_dir {
            config.base_dir = base.clone();
        }
        if let Some(input) = &self.input {
            config.input = config.resolve(input);
        }
        if let Some([x, y, w, h]) = self.crop {
            config.crop = Some((x, y, w, h));
        }
        if let Some(seed) = self.seed {
            config.seed = seed;
        }
    }
}

/// A stage built from its spec entry, with the name it was registered under (the report
/// section and the progress line).
pub struct NamedStage {
    /// The registered name (one of [`stage_names`]).
    pub name: &'static str,
    /// The stage.
    pub stage: Box<dyn Stage>,
}

impl std::fmt::Debug for NamedStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NamedStage")
            .field("name", &self.name)
            .finish()
    }
}

/// How a registered stage is built from its `params`.
type Build = fn(&serde_json::Value) -> Result<Box<dyn Stage>>;

/// The stage registry: every stage a spec may use, in the order of the default run, and how
/// each one is built from its `params`. The one list of stage names.
const REGISTRY: [(&str, Build); 12] = [
    ("load", |p| no_params(p, Box::new(load::Load))),
    ("fill_voids", |p| no_params(p, Box::new(fill::FillVoids))),
    ("convert", |p| {
        no_params(p, Box::new(convert::ConvertRoundTrips))
    }),
    ("sparse", with_params::<sparse::SparseParams>),
    ("quilt", with_params::<quilt::QuiltParams>),
    ("wavelet", with_params::<wavelet::WaveletParams>),
    ("amplify", with_params::<dictionary::AmplifyParams>),
    ("sketch", with_params::<dictionary::SketchParams>),
    ("procedural", with_params::<dictionary::ProceduralParams>),
    ("volume", with_params::<volume::VolumeParams>),
    // After every stage that changes the terrain (the last is `amplify`; sketch, procedural
    // and volume leave it as it is): the drainage of the final terrain.
    ("flow", with_params::<flow::FlowStage>),
    // Erosion of the input DEM at its own cell size (or of the terrain, `input: "terrain"`).
    ("erode", with_params::<erode::ErodeParams>),
];

/// Every stage name a spec may use, in the order of the default run.
pub fn stage_names() -> impl Iterator<Item = &'static str> {
    REGISTRY.iter().map(|(name, _)| *name)
}

/// The stages of the default run (`cargo xtask pipeline` without a spec, and the golden run):
/// every registered stage, in registry order, with its defaults.
pub fn default_spec() -> Vec<StageSpec> {
    stage_names().map(StageSpec::named).collect()
}

/// Builds one stage from its spec entry.
pub fn build_stage(spec: &StageSpec) -> Result<NamedStage> {
    let Some(&(name, build)) = REGISTRY.iter().find(|(n, _)| *n == spec.stage) else {
        bail!(
            "unknown stage `{}`; known stages: {}",
            spec.stage,
            stage_names().collect::<Vec<_>>().join(", ")
        );
    };
    let stage = build(&spec.params).with_context(|| format!("stage `{name}`"))?;
    Ok(NamedStage { name, stage })
}

/// Builds every stage of a list, naming the first one that fails.
pub fn build_stages(specs: &[StageSpec]) -> Result<Vec<NamedStage>> {
    specs
        .iter()
        .enumerate()
        .map(|(i, s)| build_stage(s).with_context(|| format!("stage #{} (`{}`)", i + 1, s.stage)))
        .collect()
}

/// Deserialises a stage's parameter struct: the spec's `params` merged recursively onto the
/// stage's defaults (objects field by field, anything else replaced), so a spec names only what
/// it changes, also inside nested job settings (`{"job": {"steps": 1}}` keeps the stage's other
/// job fields); `null` gives the defaults; an unknown field is an error.
pub fn params<T: DeserializeOwned + Serialize + Default>(value: &serde_json::Value) -> Result<T> {
    if value.is_null() {
        return Ok(T::default());
    }
    let mut merged = serde_json::to_value(T::default()).context("cannot encode the defaults")?;
    merge(&mut merged, value.clone());
    serde_json::from_value(merged).context("invalid `params`")
}

/// `over` merged onto `base`: objects field by field, anything else replaced. A one-key object
/// over a one-key object with another key is an enum variant switch (`{"poisson": {...}}` over
/// `{"feather": {...}}`) and replaces it.
fn merge(base: &mut serde_json::Value, over: serde_json::Value) {
    match (base, over) {
        (serde_json::Value::Object(b), serde_json::Value::Object(o))
            if !(b.len() == 1 && o.len() == 1 && o.keys().all(|k| !b.contains_key(k))) =>
        {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) => merge(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (b, o) => *b = o,
    }
}

/// The parameters of a stage, which run as the stage itself: read by [`params`] from the spec's
/// `params` over their [`Default`], and checked when the spec is built, so a bad spec fails
/// before any stage runs.
pub(crate) trait StageParams:
    Stage + Serialize + DeserializeOwned + Default + 'static
{
    /// Checks the parameters; an error names the parameter.
    fn check_params(&self) -> Result<()>;
}

/// Builds a stage with parameters `P` from its spec entry's `params` (read and checked).
pub(crate) fn with_params<P: StageParams>(value: &serde_json::Value) -> Result<Box<dyn Stage>> {
    let p: P = params(value)?;
    p.check_params()?;
    Ok(Box::new(p))
}

/// A stage without parameters: `params` must be absent, `null` or `{}`.
fn no_params(value: &serde_json::Value, stage: Box<dyn Stage>) -> Result<Box<dyn Stage>> {
    match value {
        serde_json::Value::Null => Ok(stage),
        serde_json::Value::Object(m) if m.is_empty() => Ok(stage),
        _ => bail!("this stage takes no parameters"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_stage_builds_and_reports_its_name() {
        for name in stage_names() {
            let stage = build_stage(&StageSpec::named(name)).unwrap();
            assert_eq!(stage.name, name);
        }
        let names: Vec<_> = stage_names().collect();
        let default: Vec<_> = default_spec().into_iter().map(|s| s.stage).collect();
        assert_eq!(default, names);
        let mut unique = names.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(
            unique.len(),
            names.len(),
            "a stage name is registered twice"
        );
    }

    #[test]
    fn unknown_stage_and_bad_params_are_named() {
        let err = build_stage(&StageSpec::named("nope")).err().unwrap();
        assert!(
            format!("{err:#}").contains("unknown stage `nope`"),
            "{err:#}"
        );
        let bad = StageSpec {
            stage: "load".into(),
            params: serde_json::json!({"x": 1}),
        };
        let err = build_stage(&bad).err().unwrap();
        assert!(
            format!("{err:#}").contains("takes no parameters"),
            "{err:#}"
        );
    }

    #[test]
    fn example_spec_in_docs_is_valid() {
        let root = crate::test_root();
        let path = root.join("docs/pipeline-spec.example.json");
        let spec = PipelineSpec::read(&path).unwrap();
        let mut config = PipelineConfig::full(&root);
        spec.apply(&mut config);
        assert!(config.input.is_file(), "{}", config.input.display());
        assert_eq!(config.base_dir, root.join("docs"));
        assert_eq!(spec.stages[0].stage, "load");
    }

    #[test]
    fn malformed_spec_is_an_error_naming_the_file() {
        let tmp = tempfile::tempdir().unwrap();
        let p = tmp.path().join("s.json");
        std::fs::write(&p, r#"{"stages": [{"stage": "load"}], "sede": 1}"#).unwrap();
        let err = PipelineSpec::read(&p).unwrap_err();
        let msg = format!("{err:#}");
        assert!(msg.contains("s.json") && msg.contains("sede"), "{msg}");
        std::fs::write(&p, r#"{"stages": []}"#).unwrap();
        let err = PipelineSpec::read(&p).unwrap_err();
        assert!(format!("{err:#}").contains("empty"), "{err:#}");
    }

    /// A spec's `params` are merged onto the stage's defaults, nested job settings included;
    /// a one-key object with another key switches an enum variant; unknown fields fail.
    #[test]
    fn params_merge_onto_the_stage_defaults() {
        use relief_dictionary_learning::DictionaryChoice;
        let p: dictionary::AmplifyParams =
            params(&serde_json::json!({"job": {"steps": 1}, "also_x4": false})).unwrap();
        let d = dictionary::AmplifyParams::default();
        assert_eq!(p.job.steps, 1);
        assert_eq!(p.job.radius, d.job.radius, "the stage's radius is kept");
        assert!(!p.also_x4 && p.replace_terrain == d.replace_terrain);
        let p: dictionary::AmplifyParams =
            params(&serde_json::json!({"job": {"dictionary": {"learned": {"n_atoms": 32}}}}))
                .unwrap();
        assert_eq!(p.job.dictionary, DictionaryChoice::learned_default(32));
        let p: dictionary::AmplifyParams =
            params(&serde_json::json!({"job": {"dictionary": "complete"}})).unwrap();
        assert_eq!(p.job.dictionary, DictionaryChoice::Complete);
        let p: wavelet::WaveletParams =
            params(&serde_json::json!({"job": {"fit": {"min_level": 2}}})).unwrap();
        assert_eq!(p.job.fit.min_level, 2);
        assert_eq!(
            p.job.fit.gamma_max,
            wavelet::WaveletParams::default().job.fit.gamma_max
        );
        for bad in [
            serde_json::json!({"job": {"stepz": 1}}),
            serde_json::json!({"jobs": {}}),
            serde_json::json!({"job": {"dictionary": {"learned": {"atoms": 3}}}}),
        ] {
            assert!(params::<dictionary::AmplifyParams>(&bad).is_err(), "{bad}");
        }
    }
}
