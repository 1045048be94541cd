//! One x4 step: coarse patches coded on `L` (Batch-OMP or the diverse atom choice), the codes
//! placed on `H`, and the residual field that makes the box reduction match the input.

use super::*;

impl MultiResDictionary {
    /// One x4 step: codes `coarse` on `L`, rebuilds on `H`; the result covers
    /// `4 w x 4 h` pixels of cell size `cell / 4`.
    pub fn amplify_once(&self, coarse: &Heightfield, settings: &AmplifySettings) -> Result<Sct> {
        self.amplify_once_in(coarse, settings, None, &relief_heightfield::NoProgress)
    }

    /// [`Self::amplify_once`] asking `progress` whether to stop between bands of coded
    /// primitives (a few tens of milliseconds apart): a run past its time budget or
    /// interrupted ends with [`LearnError::Stopped`]. Nothing is reported to it.
    pub fn amplify_once_with(
        &self,
        coarse: &Heightfield,
        settings: &AmplifySettings,
        progress: &dyn Progress,
    ) -> Result<Sct> {
        self.amplify_once_in(coarse, settings, None, progress)
    }

    /// [`Self::amplify_once`] on `coarse`, a crop of a larger step input placed by `frame`
    /// (`None`: `coarse` is the whole input): the seeded choices of the primitives hash their
    /// position in the whole input's grid, so a crop's primitives are those of the full run.
    /// `progress` is asked whether to stop before every band of primitives.
    pub(super) fn amplify_once_in(
        &self,
        coarse: &Heightfield,
        settings: &AmplifySettings,
        frame: Option<GridFrame>,
        progress: &dyn Progress,
    ) -> Result<Sct> {
        settings.check()?;
        coarse.require_complete()?;
        let geom = settings.coarse_geometry();
        if geom.patch_size * geom.patch_size != self.low.ncols() {
            return Err(LearnError::param(
                "radius",
                settings.radius,
                "does not match the dictionary's patch size",
            ));
        }
        let g = geom.grid(coarse.width(), coarse.height())?;
        let f = STEP_FACTOR as f64;
        let fine = CentreGrid {
            origin: [f * g.origin[0] + 1.5, f * g.origin[1] + 1.5],
            step: f * g.step,
            nx: g.nx,
            ny: g.ny,
        };
        if settings.exemplar_detail {
            if frame.is_some() {
                return Err(LearnError::param(
                    "exemplar_detail",
                    true,
                    "a step computed by windows needs it off (its detail gain is global)",
                ));
            }
            let patches = extract_patches(coarse, &geom)?;
            return self.exemplar_detail_step(coarse, &patches, fine, settings);
        }
        // The patches are extracted and coded in bands of centre rows, so that the patch
        // matrix of a large step (the last of x256: 2049^2 patches of 64 samples, over 1 GiB)
        // never exists whole; a primitive's code depends only on its own patch and its place
        // in the grid, so the codes are those of one batch.
        let k = geom.patch_size * geom.patch_size;
        let band = (CODE_BAND_SAMPLES / (g.nx * k).max(1)).max(1);
        let mut means = Vec::with_capacity(g.len());
        let mut codes: Option<relief_sparse_core::SparseCodes<f32>> = None;
        for r0 in (0..g.ny).step_by(band) {
            progress.check_stop(|| {
                LearnError::Stopped(format!(
                    "coding the x4 step's primitives, row {r0} of {}",
                    g.ny
                ))
            })?;
            let patches = extract_patch_rows(coarse, &geom, r0..(r0 + band).min(g.ny))?;
            let c = self.code_band(&patches.matrix, r0 * g.nx, g.nx, frame, settings)?;
            means.extend_from_slice(&patches.means);
            match &mut codes {
                Some(all) => all.append(&c),
                None => codes = Some(c),
            }
        }
        let codes = codes.ok_or_else(|| LearnError::param("coarse", 0, "gives no primitive"))?;
        let n = codes.n_signals();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let mut atoms = Vec::with_capacity(codes.nnz());
        let mut coeffs = Vec::with_capacity(codes.nnz());
        for i in 0..n {
            let (idx, val) = codes.signal(i);
            for (&j, &x) in idx.iter().zip(val) {
                atoms.push(j);
                coeffs.push(x * self.transfer[j as usize]);
            }
            offsets.push(atoms.len() as u32);
        }
        let layer = SparseLayer::from_parts(
            self.high.clone(),
            Placement::Grid(fine),
            means.clone(),
            offsets,
            atoms,
            coeffs,
        )?;
        let (cx, cy) = coarse.cell_size();
        let root = if settings.residual_correction {
            let res = self.residual_field(coarse, (&means, g), &codes, settings)?;
            Node::Add(vec![Node::Layer(layer), Node::Field(res)])
        } else {
            Node::Layer(layer)
        };
        Ok(Sct::new(
            root,
            coarse.width() * STEP_FACTOR,
            coarse.height() * STEP_FACTOR,
            (cx / f, cy / f),
        )?)
    }
}

/// Most patch samples extracted and coded at once by a step (8 MiB of `f32`): larger grids
/// are coded in bands of centre rows, so the patch matrix of a large step never exists whole
/// and a stop is asked for every few tens of milliseconds of coding.
const CODE_BAND_SAMPLES: usize = 1 << 21;

impl MultiResDictionary {
    /// The `L` codes of `signals`, the patches of primitives `first..` of a grid `nx`
    /// primitives wide (`frame`: where that grid sits in the whole input's).
    fn code_band(
        &self,
        signals: &Array2<f32>,
        first: usize,
        nx: usize,
        frame: Option<GridFrame>,
        settings: &AmplifySettings,
    ) -> Result<relief_sparse_core::SparseCodes<f32>> {
        if settings.diverse_atoms
            && settings.sparsity == 1
            && settings.patch_size() >= DIVERSE_MIN_PATCH
            && self.len() <= DIVERSE_MAX_ATOMS
        {
            let global = |i: usize| {
                let i = first + i;
                match frame {
                    Some(f) => ((f.row0 + i / nx) * f.nx + f.col0 + i % nx) as u64,
                    None => i as u64,
                }
            };
            self.diverse_codes_with(signals, settings.seed, &global)
        } else {
            Ok(relief_sparse_core::code_indexed(
                self.low.view(),
                signals.view(),
                &OmpSettings {
                    sparsity: settings.sparsity.min(self.len()),
                    tolerance: None,
                },
                settings.index_probes,
                &relief_heightfield::NoProgress,
            )?)
        }
    }
}

/// Largest `|v|` of `v` (0 for an empty slice; NaNs ignored, as by `f32::max`), in eight
/// lanes so that it vectorises: max is exact, so the lanes give the sequential fold's value.
#[inline(always)]
fn max_abs(v: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let chunks = v.chunks_exact(8);
    let tail = chunks
        .remainder()
        .iter()
        .fold(0.0f32, |m, x| m.max(x.abs()));
    for ch in chunks {
        for (l, x) in lanes.iter_mut().zip(ch) {
            *l = l.max(x.abs());
        }
    }
    lanes.iter().fold(tail, |m, &l| m.max(l))
}

/// Appends `(v, j)` for every `v = cs[j]` with `|v| >= thr`, in increasing `j` (what the
/// plain filter gives), testing eight values at a time first: few atoms come within the
/// tolerance of the best, so most blocks are skipped by one vectorised comparison.
#[inline(always)]
fn near_atoms(cs: &[f32], thr: f32, near: &mut Vec<(f32, u32)>) {
    let chunks = cs.chunks_exact(8);
    let tail = chunks.remainder();
    for (b, ch) in chunks.enumerate() {
        if ch.iter().fold(false, |any, v| any | (v.abs() >= thr)) {
            for (k, &v) in ch.iter().enumerate() {
                if v.abs() >= thr {
                    near.push((v, (8 * b + k) as u32));
                }
            }
        }
    }
    let base = cs.len() - tail.len();
    for (k, &v) in tail.iter().enumerate() {
        if v.abs() >= thr {
            near.push((v, (base + k) as u32));
        }
    }
}

/// The diverse pick of every row of a block of signals `rows` (the first is signal `first`)
/// from its correlations `corr` with the `L` atoms: a seeded choice among the atoms within
/// [`DIVERSE_TOLERANCE`] of the best, `(atom, coefficient, squared residual)`; `None` for a
/// row without a finite non-zero correlation.
#[inline(always)]
fn pick_block(
    corr: &Array2<f32>,
    rows: ndarray::ArrayView2<'_, f32>,
    (first, seed): (usize, u64),
    index: &(dyn Fn(usize) -> u64 + Sync),
) -> Vec<Option<(u32, f32, f32)>> {
    let mut out = Vec::with_capacity(rows.nrows());
    let mut near: Vec<(f32, u32)> = Vec::new();
    for (r, (c, x)) in corr.outer_iter().zip(rows.outer_iter()).enumerate() {
        let i = first + r;
        let best = c
            .as_slice()
            .map_or_else(|| c.iter().fold(0.0f32, |m, v| m.max(v.abs())), max_abs);
        if !(best > 0.0 && best.is_finite()) {
            out.push(None);
            continue;
        }
        near.clear();
        let thr = DIVERSE_TOLERANCE * best;
        match c.as_slice() {
            Some(cs) => near_atoms(cs, thr, &mut near),
            None => near.extend(
                c.iter()
                    .enumerate()
                    .filter(|(_, v)| v.abs() >= thr)
                    .map(|(j, &v)| (v, j as u32)),
            ),
        }
        // Strongest first, ties by atom: a total order, so keeping only the first
        // DIVERSE_CHOICES before sorting gives the same list.
        let order =
            |p: &(f32, u32), q: &(f32, u32)| q.0.abs().total_cmp(&p.0.abs()).then(p.1.cmp(&q.1));
        if near.len() > DIVERSE_CHOICES {
            near.select_nth_unstable_by(DIVERSE_CHOICES - 1, order);
            near.truncate(DIVERSE_CHOICES);
        }
        near.sort_unstable_by(order);
        let k = near.len().min(DIVERSE_CHOICES);
        let (v, j) = near[(item_seed(seed, 0xd17e, index(i)) % k as u64) as usize];
        let e: f32 = x.iter().map(|t| t * t).sum();
        out.push(Some((j, v, (e - v * v).max(0.0))));
    }
    out
}

relief_sparse_core::avx2_dispatch! {
    /// [`pick_block`], compiled with AVX2 where the CPU has it (wider vectors for the scans of
    /// the correlations; the picks are bit-identical, see
    /// [`avx2_dispatch!`](relief_sparse_core::avx2_dispatch)).
    fn pick_block_dispatch(
        corr: &Array2<f32>,
        rows: ndarray::ArrayView2<'_, f32>,
        first: (usize, u64),
        index: &(dyn Fn(usize) -> u64 + Sync),
    ) -> Vec<Option<(u32, f32, f32)>> => pick_block;
}

/// Where a crop of a step input sits in the whole input's primitive grid: its first primitive
/// is at column `col0`, row `row0` of a grid `nx` primitives wide.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct GridFrame {
    pub(super) col0: usize,
    pub(super) row0: usize,
    pub(super) nx: usize,
}

/// Largest dictionary coded with the diverse atom choice ([`AmplifySettings::diverse_atoms`]);
/// larger ones keep the exact nearest-atom search.
pub const DIVERSE_MAX_ATOMS: usize = 4096;
/// Smallest coarse patch side coded with the diverse atom choice: a `2 x 2` patch (radius
/// below 2) has 3 degrees of freedom once mean-removed, so 90 % of the best correlation is no
/// near match (on the 128^2 golden crop at radius 1 the slope-histogram distance grew from
/// 0.75 to 1.14 degrees); the best atom is kept there.
pub const DIVERSE_MIN_PATCH: usize = 4;
/// Relative correlation an atom needs to be a choice of [`AmplifySettings::diverse_atoms`].
pub const DIVERSE_TOLERANCE: f32 = 0.9;
/// Most atoms a primitive chooses among ([`AmplifySettings::diverse_atoms`]).
pub const DIVERSE_CHOICES: usize = 8;

impl MultiResDictionary {
    /// `s = 1` codes of the rows of `signals` with the diverse atom choice (see
    /// [`AmplifySettings::diverse_atoms`]): correlations with every `L` atom by blocked matrix
    /// products, then a seeded pick among the near-best atoms. Deterministic whatever the
    /// thread count (the pick depends only on the seed and the signal index).
    pub fn diverse_codes(
        &self,
        signals: &Array2<f32>,
        seed: u64,
    ) -> Result<relief_sparse_core::SparseCodes<f32>> {
        self.diverse_codes_with(signals, seed, &|i| i as u64)
    }

    /// [`Self::diverse_codes`] with the hashed index of signal `i` given by `index`.
    fn diverse_codes_with(
        &self,
        signals: &Array2<f32>,
        seed: u64,
        index: &(dyn Fn(usize) -> u64 + Sync),
    ) -> Result<relief_sparse_core::SparseCodes<f32>> {
        use rayon::prelude::*;
        if signals.ncols() != self.low.ncols() {
            return Err(LearnError::param(
                "signals",
                signals.ncols(),
                "dimension differs from the coarse patch",
            ));
        }
        const BLOCK: usize = 512;
        let n = signals.nrows();
        let lt = self.low.t();
        let picks: Vec<Option<(u32, f32, f32)>> = (0..n.div_ceil(BLOCK))
            .into_par_iter()
            .flat_map_iter(|b| {
                let rows = signals.slice(ndarray::s![b * BLOCK..((b + 1) * BLOCK).min(n), ..]);
                let corr = rows.dot(&lt);
                pick_block_dispatch(&corr, rows, (b * BLOCK, seed), index)
            })
            .collect();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0usize);
        let (mut idx, mut val, mut res) = (Vec::new(), Vec::new(), Vec::with_capacity(n));
        for (i, p) in picks.into_iter().enumerate() {
            match p {
                Some((j, v, r)) => {
                    idx.push(j);
                    val.push(v);
                    res.push(r);
                }
                None => res.push(signals.row(i).iter().map(|t| t * t).sum()),
            }
            offsets.push(idx.len());
        }
        Ok(relief_sparse_core::SparseCodes::from_parts(
            offsets, idx, val, res,
        )?)
    }

    /// The coarse prediction of `box-down(H layer)`: the footprints of the codes, rasterised
    /// on the coarse grid.
    fn footprint_raster(
        &self,
        coarse: &Heightfield,
        (means, grid): (&[f32], CentreGrid),
        codes: &relief_sparse_core::SparseCodes<f32>,
    ) -> Result<Heightfield> {
        let n = codes.n_signals();
        let mut z = means.to_vec();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let (mut atoms, mut coeffs) = (Vec::new(), Vec::new());
        for (i, zi) in z.iter_mut().enumerate() {
            let (idx, val) = codes.signal(i);
            let mut shift = 0.0f64;
            for (&j, &x) in idx.iter().zip(val) {
                let j = j as usize;
                shift += x as f64 * self.footprint_mean[j] as f64;
                if self.footprint_scale[j] > 0.0 {
                    atoms.push(j as u32);
                    coeffs.push(x * self.footprint_scale[j]);
                }
            }
            *zi = (*zi as f64 + shift) as f32;
            offsets.push(atoms.len() as u32);
        }
        let layer = SparseLayer::from_parts(
            self.footprint.clone(),
            Placement::Grid(grid),
            z,
            offsets,
            atoms,
            coeffs,
        )?;
        Ok(Sct::new(
            Node::Layer(layer),
            coarse.width(),
            coarse.height(),
            coarse.cell_size(),
        )?
        .rasterize(&RasterSettings::default())?)
    }

    /// The residual (see [`AmplifySettings::residual_correction`]): the difference between
    /// the input and the predicted `box-down` of the detail layer, back-projected so that its
    /// x4 interpolation reduces (box) to it, as a field node on the coarse grid (sample `k`
    /// at fine pixel `4 k + 1.5`).
    fn residual_field(
        &self,
        coarse: &Heightfield,
        primitives: (&[f32], CentreGrid),
        codes: &relief_sparse_core::SparseCodes<f32>,
        settings: &AmplifySettings,
    ) -> Result<Field> {
        let rec = self.footprint_raster(coarse, primitives, codes)?;
        let (d, _) = relief_heightfield::metrics::difference_field(coarse, &rec)?;
        let kernel = settings.residual_kernel;
        let r = back_project(&d, coarse.width(), coarse.height(), kernel);
        let f = STEP_FACTOR as f64;
        Ok(Field::new(
            coarse.width(),
            coarse.height(),
            r.iter().map(|&v| v as f32).collect(),
            [1.5, 1.5],
            f,
            kernel,
        )?)
    }
}

/// A smooth field interpolated x4 as a fine-grid layer of its own patches (complete
/// dictionary, atoms sampled every 4 fine pixels, centres every `R` coarse pixels): the
/// low part of [`AmplifySettings::exemplar_detail`].
pub(crate) fn interpolation_layer(
    field: &Heightfield,
    settings: &AmplifySettings,
) -> Result<SparseLayer> {
    // One smooth field: primitives one radius apart interpolate it as well as a denser grid,
    // at a quarter of the primitives.
    let geom = PatchGeometry {
        step: settings.radius.floor().max(1.0),
        ..settings.coarse_geometry()
    };
    let rp = extract_patches(field, &geom)?;
    let f = STEP_FACTOR as f64;
    let fine = CentreGrid {
        origin: [f * rp.grid.origin[0] + 1.5, f * rp.grid.origin[1] + 1.5],
        step: f * rp.grid.step,
        nx: rp.grid.nx,
        ny: rp.grid.ny,
    };
    let mut dict = Dictionary::new(geom.patch_size, f, geom.support_radius * f)?;
    let mut offsets = vec![0u32];
    let (mut atoms, mut coeffs) = (Vec::new(), Vec::new());
    for row in rp.matrix.outer_iter() {
        let v: Vec<f32> = row.iter().copied().collect();
        let norm = v.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
        match dict.push_data(&v) {
            Ok(j) => {
                atoms.push(j as u32);
                coeffs.push(norm as f32);
            }
            Err(relief_sparse_core::SparseError::DegenerateAtom { .. }) => {}
            Err(e) => return Err(e.into()),
        }
        offsets.push(atoms.len() as u32);
    }
    if dict.is_empty() {
        // A field without relief: one harmless atom, used by nobody.
        let mut v = vec![0f32; geom.patch_size * geom.patch_size];
        v[0] = 1.0;
        dict.push_data(&v)?;
    }
    Ok(SparseLayer::from_parts(
        Arc::new(dict),
        Placement::Grid(fine),
        rp.means.clone(),
        offsets,
        atoms,
        coeffs,
    )?)
}
