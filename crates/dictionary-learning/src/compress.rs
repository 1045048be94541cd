//! The compress job (guerin2016 section 5.1) as one unit: [`CompressSettings`] (serde,
//! [`CompressSettings::check`]) run on a terrain by [`CompressSettings::run`], which returns the
//! Sparse Construction Tree and its [`CompressFigures`]. `relief compress` and the pipeline's
//! `sparse` stage both go through it, so a parameter is defined once.

use relief_heightfield::param::in_range;
use std::sync::Arc;
use std::time::Instant;

use relief_heightfield::{Heightfield, Progress};
use relief_sparse_core::{
    CompressionReport, Dictionary, EncodeSettings, FormatOptions, FunctionAtomRegistry,
    PatchGeometry, Sct, compression_report, encode_with_progress, extract_patches,
};
use serde::{Deserialize, Serialize};

use crate::error::{LearnError, Result};
use crate::ksvd::{KsvdSettings, MAX_ITERATIONS, ksvd};
use crate::noise::{NoiseFamily, random_function_atoms, register_function_atoms};

/// Most analytic atoms [`CompressSettings::analytic_atoms`] may add.
const MAX_ANALYTIC_ATOMS: usize = 65_536;

/// Where the dictionary of a compress job comes from (when none is given to
/// [`CompressSettings::run`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DictionarySource {
    /// Approximate K-SVD learned on the terrain's own patches (section 4.4).
    #[default]
    Ksvd,
    /// `atoms` patches of the terrain picked evenly (no learning).
    Sample,
    /// Every patch is its own atom (section 4.3): exact with `s = 1`, but `N = n` atoms.
    Complete,
}

/// Settings of the compress job. JSON: missing fields take these defaults, unknown fields are an
/// error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompressSettings {
    /// Sparsity `s`: atoms per primitive (1..=64, at most the number of atoms).
    pub sparsity: usize,
    /// Number of atoms `N` of a learned or sampled dictionary.
    pub atoms: usize,
    /// Dictionary source.
    pub source: DictionarySource,
    /// Patch side `a` in samples (`K = a^2`).
    pub patch_size: usize,
    /// Sample spacing `delta` of the patches, in cells.
    pub spacing: f64,
    /// Support radius `R` in cells (`None`: half the patch width, `a delta / 2`).
    pub radius: Option<f64>,
    /// Step between primitive centres in cells (`None`: half the patch width).
    pub step: Option<f64>,
    /// Stop a patch's OMP early once its squared residual is at most this (m^2).
    pub tolerance: Option<f64>,
    /// Store coefficients as 16-bit integers (smaller file, slightly lower PSNR).
    pub quantize: bool,
    /// K-SVD iterations.
    pub iterations: usize,
    /// Seed of the K-SVD initialisation (and of the analytic atoms' parameters).
    pub seed: u64,
    /// Analytic (noise function) atoms appended to the data dictionary, so that every
    /// primitive's OMP chooses freely between data and analytic atoms (the paper's mixed
    /// dictionaries, figure 14). Not used with a given dictionary.
    pub analytic_atoms: AnalyticAtoms,
    /// With `s = 1` and more than 4096 atoms (e.g. a complete dictionary): clusters of the
    /// inverted-list atom index searched per patch (0 = the exact search; any count at or above the number of clusters searches them all). See
    /// [`relief_sparse_core::DEFAULT_INDEX_PROBES`].
    pub index_probes: usize,
}

/// How many random analytic atoms of each family [`CompressSettings::analytic_atoms`] adds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnalyticAtoms {
    /// Sums of ridged noise (figure 4).
    pub ridged_sum: usize,
    /// Perlin fBm.
    pub perlin: usize,
    /// Ridged multifractal noise.
    pub ridged_multifractal: usize,
    /// Windows of one fBm field at terrain scale ([`NoiseFamily::PerlinField`]).
    pub perlin_field: usize,
    /// Windows of one ridged multifractal field at terrain scale
    /// ([`NoiseFamily::RidgedField`]).
    pub ridged_field: usize,
}

impl AnalyticAtoms {
    /// Atoms in all.
    pub fn total(&self) -> usize {
        self.ridged_sum
            + self.perlin
            + self.ridged_multifractal
            + self.perlin_field
            + self.ridged_field
    }

    fn families(&self) -> [(NoiseFamily, usize); 5] {
        [
            (NoiseFamily::RidgedSum, self.ridged_sum),
            (NoiseFamily::Perlin, self.perlin),
            (NoiseFamily::RidgedMultifractal, self.ridged_multifractal),
            (NoiseFamily::PerlinField, self.perlin_field),
            (NoiseFamily::RidgedField, self.ridged_field),
        ]
    }
}

impl Default for CompressSettings {
    fn default() -> Self {
        Self {
            sparsity: 2,
            atoms: 128,
            source: DictionarySource::Ksvd,
            patch_size: 8,
            spacing: 1.0,
            radius: None,
            step: None,
            tolerance: None,
            quantize: false,
            iterations: 10,
            seed: 0,
            analytic_atoms: AnalyticAtoms::default(),
            index_probes: relief_sparse_core::DEFAULT_INDEX_PROBES,
        }
    }
}

/// What a compress job reports: the dictionary and the paper's table 1 columns (`report`,
/// flattened in JSON).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompressFigures {
    /// How the dictionary was made.
    pub dictionary: String,
    /// Atom side `a` (`K = a^2`).
    pub patch_size: usize,
    /// Sample spacing `delta` of the atoms.
    pub spacing: f64,
    /// Support radius `R`.
    pub radius: f64,
    /// Storage, size and reconstruction error.
    #[serde(flatten)]
    pub report: CompressionReport,
    /// Seconds spent making the dictionary.
    pub dictionary_seconds: f64,
    /// Seconds spent encoding.
    pub encode_seconds: f64,
}

/// Result of [`CompressSettings::run`].
#[derive(Debug, Clone)]
pub struct Compressed {
    /// The Sparse Construction Tree.
    pub sct: Sct,
    /// Its serialised bytes (`.sct`, with the job's quantisation).
    pub bytes: Vec<u8>,
    /// Its figures.
    pub figures: CompressFigures,
}

impl CompressSettings {
    /// Validates the settings (the dictionary-dependent checks run in [`Self::run`]).
    pub fn check(&self) -> Result<()> {
        in_range("sparsity", self.sparsity, 1..=64, "must be in 1..=64")?;
        if self.source != DictionarySource::Complete && self.atoms == 0 {
            return Err(LearnError::param("atoms", 0, "must be >= 1"));
        }
        in_range("patch_size", self.patch_size, 2..=64, "must be in 2..=64")?;
        if !(self.spacing.is_finite() && self.spacing > 0.0 && self.spacing <= 1e3) {
            return Err(LearnError::param(
                "spacing",
                self.spacing,
                "must be in (0, 1000] cells",
            ));
        }
        for (name, v) in [("radius", self.radius), ("step", self.step)] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return Err(LearnError::param(name, v, "must be finite and > 0"));
            }
        }
        if self.iterations > MAX_ITERATIONS {
            return Err(LearnError::param(
                "iterations",
                self.iterations,
                "must be <= 10000",
            ));
        }
        if self.analytic_atoms.total() > MAX_ANALYTIC_ATOMS {
            return Err(LearnError::param(
                "analytic_atoms",
                self.analytic_atoms.total(),
                "must be <= 65536 in all",
            ));
        }
        Ok(())
    }

    /// The patch geometry of a dictionary made by this job.
    pub fn geometry(&self) -> PatchGeometry {
        let half = self.patch_size as f64 * self.spacing / 2.0;
        PatchGeometry {
            patch_size: self.patch_size,
            spacing: self.spacing,
            step: self.step.unwrap_or(half),
            support_radius: self.radius.unwrap_or(half),
        }
    }

    /// Makes the dictionary of [`Self::source`] from the terrain's patches; returns it and a
    /// description.
    pub fn dictionary(
        &self,
        hf: &Heightfield,
        progress: &dyn Progress,
    ) -> Result<(Dictionary, String)> {
        self.check()?;
        let geometry = self.geometry();
        let patches = extract_patches(hf, &geometry)?;
        let n = patches.matrix.nrows();
        match self.source {
            DictionarySource::Complete => {
                let (d, _) = Dictionary::from_patches(&patches, None)?;
                Ok((d, "complete (every patch an atom)".into()))
            }
            DictionarySource::Sample => {
                if self.atoms > n {
                    return Err(LearnError::NotEnough {
                        what: "patches to sample `atoms` from",
                        needed: self.atoms,
                        got: n,
                    });
                }
                let sel: Vec<usize> = (0..self.atoms).map(|k| k * n / self.atoms).collect();
                let (d, _) = Dictionary::from_patches(&patches, Some(&sel))?;
                if d.is_empty() {
                    return Err(LearnError::param(
                        "source",
                        "sample",
                        "every sampled patch is flat: no atom (use ksvd or more atoms)",
                    ));
                }
                let what = format!("{} patches sampled evenly", d.len());
                Ok((d, what))
            }
            DictionarySource::Ksvd => {
                let learned = ksvd(
                    patches.matrix.view(),
                    &KsvdSettings {
                        n_atoms: self.atoms,
                        sparsity: self.sparsity,
                        iterations: self.iterations,
                        seed: self.seed,
                        ..Default::default()
                    },
                    progress,
                )?;
                let d = Dictionary::from_matrix(
                    learned.atoms.view(),
                    self.patch_size,
                    geometry.spacing,
                    geometry.support_radius,
                )?;
                Ok((
                    d,
                    format!(
                        "K-SVD, {} iterations on {n} patches, seed {}",
                        self.iterations, self.seed
                    ),
                ))
            }
        }
    }

    /// Runs the job on a void-free terrain: makes the dictionary (or uses `given`, with its own
    /// patch geometry; then `source`, `atoms`, `patch_size`, `spacing` and `radius` are not
    /// used), encodes with Batch-OMP and serialises the tree.
    pub fn run(
        &self,
        hf: &Heightfield,
        given: Option<(Dictionary, String)>,
        progress: &dyn Progress,
    ) -> Result<Compressed> {
        self.check()?;
        hf.require_complete()?;
        let t = Instant::now();
        let (dict, source) = match given {
            Some(d) => d,
            None => {
                let (mut dict, mut source) = self.dictionary(hf, progress)?;
                for (family, n) in self.analytic_atoms.families() {
                    if n == 0 {
                        continue;
                    }
                    for atom in random_function_atoms(family, n, self.seed) {
                        dict.push_function(atom)?;
                    }
                    source.push_str(&format!(" + {n} analytic {family:?} atoms"));
                }
                (dict, source)
            }
        };
        let dictionary_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let sct = encode_with_progress(
            hf,
            Arc::new(dict),
            &EncodeSettings {
                sparsity: self.sparsity,
                tolerance: self.tolerance,
                step: self.step,
                index_probes: self.index_probes,
            },
            progress,
        )?;
        let encode_seconds = t.elapsed().as_secs_f64();
        let options = FormatOptions {
            quantize_coefficients: self.quantize,
        };
        let bytes = sct.to_bytes_with(&options)?;
        let mut registry = FunctionAtomRegistry::new();
        register_function_atoms(&mut registry);
        let report = compression_report(hf, &sct, &options, &registry)?;
        let d = sct.layers()[0].dictionary();
        let figures = CompressFigures {
            dictionary: source,
            patch_size: d.patch_size(),
            spacing: d.spacing(),
            radius: d.support_radius(),
            report,
            dictionary_seconds,
            encode_seconds,
        };
        Ok(Compressed {
            sct,
            bytes,
            figures,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relief_heightfield::NoProgress;

    fn terrain() -> Heightfield {
        Heightfield::from_fn(48, 40, 10.0, 10.0, |x, y| {
            let (x, y) = (x as f32, y as f32);
            60.0 * (x * 0.13).sin() * (y * 0.09).cos() + 8.0 * (x * 0.7 + y * 0.4).sin()
        })
    }

    /// A K-SVD dictionary of 16 atoms learned in `iterations` (small and quick).
    fn sixteen_atoms(iterations: usize) -> CompressSettings {
        CompressSettings {
            atoms: 16,
            iterations,
            ..Default::default()
        }
    }

    #[test]
    fn settings_round_trip_and_refuse_unknown_fields() {
        let s = CompressSettings {
            source: DictionarySource::Sample,
            radius: Some(5.0),
            quantize: true,
            ..CompressSettings::default()
        };
        relief_testdata::assert_json_round_trip(&s, &["\"source\":\"sample\""]);
        assert!(serde_json::from_str::<CompressSettings>(r#"{"dict": "ksvd"}"#).is_err());
    }

    #[test]
    fn bad_settings_are_named() {
        type Spoil = fn(&mut CompressSettings);
        let cases: [(&str, Spoil); 6] = [
            ("sparsity", |s| s.sparsity = 0),
            ("patch_size", |s| s.patch_size = 1),
            ("spacing", |s| s.spacing = f64::NAN),
            ("step", |s| s.step = Some(-1.0)),
            ("iterations", |s| s.iterations = usize::MAX),
            ("analytic_atoms", |s| s.analytic_atoms.perlin = 70_000),
        ];
        for (name, spoil) in cases {
            let mut s = CompressSettings::default();
            spoil(&mut s);
            let e = s.check().unwrap_err().to_string();
            assert!(e.contains(name), "{name}: {e}");
        }
    }

    /// Mixed dictionaries (figure 14): the analytic atoms join the learned ones, OMP may pick
    /// either, and the tree round-trips through its bytes with the noise atoms' registry.
    #[test]
    fn analytic_atoms_join_the_dictionary() {
        let hf = terrain();
        let s = CompressSettings {
            analytic_atoms: AnalyticAtoms {
                ridged_sum: 8,
                perlin: 4,
                ..Default::default()
            },
            ..sixteen_atoms(2)
        };
        let out = s.run(&hf, None, &NoProgress).unwrap();
        let d = out.sct.layers()[0].dictionary().clone();
        assert_eq!(d.len(), 16 + 12);
        assert!(!d.is_data_only());
        assert_eq!(out.figures.report.n_atoms, 28);
        // Storage counts the analytic atoms by their parameters, not K samples each.
        let params: u64 = d.atoms()[16..]
            .iter()
            .map(|a| match a {
                relief_sparse_core::dictionary::Atom::Function { func, .. } => {
                    func.descriptor().params.len() as u64
                }
                relief_sparse_core::dictionary::Atom::Data(_) => panic!("data atom at the end"),
            })
            .sum();
        let n = out.sct.layers()[0].len() as u64;
        let s2 = out.sct.layers()[0].max_sparsity() as u64;
        assert_eq!(
            out.figures.report.t,
            64 * 16 + params + n * (2 * s2 + 2) + 1
        );
        assert!(params < 64 * 12);
        assert!(
            out.figures.dictionary.contains("8 analytic RidgedSum"),
            "{}",
            out.figures.dictionary
        );
        let mut registry = FunctionAtomRegistry::new();
        register_function_atoms(&mut registry);
        let back = Sct::from_bytes(&out.bytes, &registry).unwrap();
        for (x, y) in [(3.0, 4.0), (20.5, 17.25), (40.0, 33.0)] {
            assert_eq!(back.eval(x, y), out.sct.eval(x, y));
        }
        // The same seed gives the same atoms and the same tree.
        assert_eq!(s.run(&hf, None, &NoProgress).unwrap().bytes, out.bytes);
    }

    #[test]
    fn run_reports_the_tree_it_returns() {
        let hf = terrain();
        let s = CompressSettings {
            sparsity: 2,
            seed: 5,
            ..sixteen_atoms(3)
        };
        let out = s.run(&hf, None, &NoProgress).unwrap();
        let f = &out.figures;
        assert_eq!(f.report.n_atoms, 16);
        assert_eq!(f.patch_size, 8);
        assert_eq!(f.report.n_patches, out.sct.layers()[0].len());
        assert_eq!(f.report.bytes, out.bytes.len());
        assert_eq!(f.report.t0, 48 * 40);
        assert!(f.report.psnr > 20.0, "psnr {}", f.report.psnr);
        let json = serde_json::to_value(f).unwrap();
        assert_eq!(json["psnr"], f.report.psnr);
        // Same settings, same bytes; another seed, another dictionary.
        let again = s.run(&hf, None, &NoProgress).unwrap();
        assert_eq!(again.bytes, out.bytes);
        let other = CompressSettings { seed: 6, ..s }
            .run(&hf, None, &NoProgress)
            .unwrap();
        assert_ne!(other.bytes, out.bytes);
        // Sampling more atoms than patches is an error naming it.
        let e = CompressSettings {
            source: DictionarySource::Sample,
            atoms: 100_000,
            ..s
        }
        .run(&hf, None, &NoProgress)
        .unwrap_err()
        .to_string();
        assert!(e.contains("atoms"), "{e}");
        let mut holes = hf.clone();
        holes.set(3, 3, f32::NAN);
        assert!(s.run(&holes, None, &NoProgress).is_err());
    }
}
