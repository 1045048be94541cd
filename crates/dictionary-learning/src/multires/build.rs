//! Building the `(H, L)` pairs: candidate patch pairs of the exemplars, the atoms chosen
//! among them (complete or constrained learning) and their coarse footprints.

use super::*;

struct Candidates {
    low: Array2<f32>,
    high: Vec<Vec<f32>>,
    origins: Vec<[f64; 2]>,
}

fn masked_mean_removed(v: &mut [f64], mask: &[bool]) {
    let (s, c) = v
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .fold((0.0, 0usize), |(s, c), (x, _)| (s + x, c + 1));
    let mean = s / c.max(1) as f64;
    v.iter_mut().for_each(|x| *x -= mean);
}

/// Candidate (L, H) patch pairs of an exemplar whose size is a multiple of 4.
fn candidates(exemplar: &Heightfield, settings: &AmplifySettings) -> Result<Candidates> {
    let a = settings.patch_size();
    let ah = STEP_FACTOR * a;
    let (w, h) = (
        exemplar.width() / STEP_FACTOR * STEP_FACTOR,
        exemplar.height() / STEP_FACTOR * STEP_FACTOR,
    );
    let ex = exemplar.crop(0, 0, w, h)?;
    let low = ex.resample(w / STEP_FACTOR, h / STEP_FACTOR)?;
    let (wl, hl) = (low.width(), low.height());
    if wl < a || hl < a {
        return Err(LearnError::NotEnough {
            what: "exemplar pixels (the x4-reduced exemplar must hold one patch)",
            needed: a * STEP_FACTOR,
            got: exemplar.width().min(exemplar.height()),
        });
    }
    let mask_l = Dictionary::new(a, 1.0, settings.radius)?
        .support_mask()
        .to_vec();
    let mask_h = Dictionary::new(ah, 1.0, settings.radius * STEP_FACTOR as f64)?
        .support_mask()
        .to_vec();
    // Patch top-left corners (x0, y0) in the reduced exemplar; the H patch starts at 4 x0.
    let cs = settings.candidate_step;
    let mut corners = Vec::new();
    let mut y0 = 0;
    while y0 + a <= hl {
        let mut x0 = 0;
        while x0 + a <= wl {
            corners.push((x0, y0));
            x0 += cs;
        }
        y0 += cs;
    }
    let cap = match settings.dictionary {
        DictionaryChoice::Complete => settings.max_candidates,
        DictionaryChoice::Learned { .. } => settings.max_candidates.min(settings.max_learning_pool),
    };
    if corners.len() > cap {
        let mut rng = Pcg64Mcg::seed_from_u64(item_seed(settings.seed, 0xca, corners.len() as u64));
        let mut pick = sample(&mut rng, corners.len(), cap).into_vec();
        pick.sort_unstable();
        corners = pick.into_iter().map(|i| corners[i]).collect();
    }
    let gain = settings.normalize_detail.then(|| {
        let f = STEP_FACTOR as f64;
        detail_gain(ah, f * settings.grid_step(), f * settings.radius)
    });
    let lv = low.view();
    let hv = ex.view();
    let mut lows = Vec::with_capacity(corners.len() * a * a);
    let mut highs = Vec::with_capacity(corners.len());
    let mut origins = Vec::with_capacity(corners.len());
    let mut buf = vec![0f64; a * a];
    let mut hbuf = vec![0f64; ah * ah];
    for &(x0, y0) in &corners {
        for r in 0..a {
            for c in 0..a {
                buf[r * a + c] = lv[(y0 + r, x0 + c)] as f64;
            }
        }
        masked_mean_removed(&mut buf, &mask_l);
        let (hx, hy) = (x0 * STEP_FACTOR, y0 * STEP_FACTOR);
        for r in 0..ah {
            for c in 0..ah {
                hbuf[r * ah + c] = hv[(hy + r, hx + c)] as f64;
            }
        }
        masked_mean_removed(&mut hbuf, &mask_h);
        if let Some(gain) = &gain {
            let up = upsample4(&buf, a);
            for ((hv, &lv), &g) in hbuf.iter_mut().zip(&up).zip(gain) {
                *hv = lv + g * (*hv - lv);
            }
            masked_mean_removed(&mut hbuf, &mask_h);
        }
        lows.extend(buf.iter().map(|&v| v as f32));
        highs.push(hbuf.iter().map(|&v| v as f32).collect());
        origins.push([
            x0 as f64 + (a as f64 - 1.0) / 2.0,
            y0 as f64 + (a as f64 - 1.0) / 2.0,
        ]);
    }
    let low = Array2::from_shape_vec((corners.len(), a * a), lows)
        .map_err(|_| LearnError::param("candidates", corners.len(), "internal shape error"))?;
    Ok(Candidates {
        low,
        high: highs,
        origins,
    })
}

impl MultiResDictionary {
    /// Builds `(H, L)` from an exemplar at the TARGET resolution. `training` (coarse patches to
    /// be coded, mean-removed rows) drives constrained learning when it is asked for; the
    /// exemplar's own low patches are added to it.
    pub fn from_exemplar(
        exemplar: &Heightfield,
        training: Option<ndarray::ArrayView2<f32>>,
        settings: &AmplifySettings,
        progress: &dyn Progress,
    ) -> Result<Self> {
        Self::from_exemplars(std::slice::from_ref(exemplar), training, settings, progress)
    }

    /// [`Self::from_exemplar`] over several exemplars at once (all at the target resolution):
    /// their candidate pairs are pooled (each exemplar capped at `max_candidates`).
    pub fn from_exemplars(
        exemplars: &[Heightfield],
        training: Option<ndarray::ArrayView2<f32>>,
        settings: &AmplifySettings,
        progress: &dyn Progress,
    ) -> Result<Self> {
        settings.check()?;
        let cand = pooled_candidates(exemplars, settings)?;
        let norms: Vec<f64> = cand
            .low
            .outer_iter()
            .map(|r| r.iter().map(|&v| v as f64 * v as f64).sum::<f64>().sqrt())
            .collect();
        let hnorms: Vec<f64> = cand
            .high
            .iter()
            .map(|r| r.iter().map(|&v| v as f64 * v as f64).sum::<f64>().sqrt())
            .collect();
        // Usable pairs: both patches carry relief.
        let usable: Vec<usize> = (0..norms.len())
            .filter(|&i| norms[i] > 1e-6 && hnorms[i] > 1e-6)
            .collect();
        let chosen = choose_atoms(&cand, &usable, training, settings, progress)?;
        if chosen.is_empty() {
            return Err(LearnError::NotEnough {
                what: "exemplar patches with relief",
                needed: 1,
                got: 0,
            });
        }
        let a = settings.patch_size();
        let mut low = Array2::<f32>::zeros((chosen.len(), a * a));
        let mut high = Dictionary::new(STEP_FACTOR * a, 1.0, settings.radius * STEP_FACTOR as f64)?;
        let mut transfer = Vec::with_capacity(chosen.len());
        let mut low_norm = Vec::with_capacity(chosen.len());
        let mut origins = Vec::with_capacity(chosen.len());
        let mut footprint = Dictionary::new(a, 1.0, settings.radius)?;
        let mut footprint_scale = Vec::with_capacity(chosen.len());
        let mut footprint_mean = Vec::with_capacity(chosen.len());
        for (j, &c) in chosen.iter().enumerate() {
            low.row_mut(j)
                .iter_mut()
                .zip(cand.low.row(c))
                .for_each(|(o, &v)| *o = (v as f64 / norms[c]) as f32);
            high.push_data(&cand.high[c])?;
            transfer.push((hnorms[c] / norms[c]) as f32);
            low_norm.push(norms[c] as f32);
            origins.push(cand.origins[c]);
            let mut b = box_down4(&cand.high[c], a);
            b.iter_mut().for_each(|v| *v /= norms[c]);
            let (mean, cnt) = b
                .iter()
                .zip(footprint.support_mask())
                .filter(|(_, m)| **m)
                .fold((0.0, 0usize), |(s, c), (v, _)| (s + v, c + 1));
            let mean = mean / cnt.max(1) as f64;
            let norm = b
                .iter()
                .map(|v| (v - mean) * (v - mean))
                .sum::<f64>()
                .sqrt();
            let row: Vec<f32> = b.iter().map(|&v| v as f32).collect();
            match footprint.push_data(&row) {
                Ok(_) => footprint_scale.push(norm as f32),
                Err(relief_sparse_core::SparseError::DegenerateAtom { .. }) => {
                    let mut v = vec![0f32; a * a];
                    v[0] = 1.0;
                    footprint.push_data(&v)?;
                    footprint_scale.push(0.0);
                }
                Err(e) => return Err(e.into()),
            }
            footprint_mean.push(mean as f32);
        }
        Ok(Self {
            low,
            high: Arc::new(high),
            transfer,
            origins,
            footprint: Arc::new(footprint),
            footprint_scale,
            footprint_mean,
            low_norm,
            detail_rms: None,
        })
    }

    /// Number of atoms `N`.
    pub fn len(&self) -> usize {
        self.transfer.len()
    }

    /// True when there is no atom.
    pub fn is_empty(&self) -> bool {
        self.transfer.is_empty()
    }
}

/// The candidate pairs of every exemplar (each with its own seed), pooled.
fn pooled_candidates(exemplars: &[Heightfield], settings: &AmplifySettings) -> Result<Candidates> {
    if exemplars.is_empty() {
        return Err(LearnError::NotEnough {
            what: "exemplars",
            needed: 1,
            got: 0,
        });
    }
    let mut parts = Vec::with_capacity(exemplars.len());
    for (i, e) in exemplars.iter().enumerate() {
        e.require_complete()?;
        let st = AmplifySettings {
            seed: item_seed(settings.seed, 0xe7, i as u64),
            ..*settings
        };
        parts.push(candidates(e, &st)?);
    }
    let cand = if parts.len() == 1 {
        parts.pop().ok_or(LearnError::NotEnough {
            what: "exemplars",
            needed: 1,
            got: 0,
        })?
    } else {
        let views: Vec<_> = parts.iter().map(|p| p.low.view()).collect();
        let low = ndarray::concatenate(ndarray::Axis(0), &views)
            .map_err(|_| LearnError::param("exemplars", parts.len(), "internal shape error"))?;
        let mut high = Vec::new();
        let mut origins = Vec::new();
        for p in parts {
            high.extend(p.high);
            origins.extend(p.origins);
        }
        Candidates { low, high, origins }
    };
    Ok(cand)
}

/// The candidates (indices into `usable`, the pairs with relief) that become atoms: all of them
/// for a complete dictionary, those constrained learning picks for a learned one.
fn choose_atoms(
    cand: &Candidates,
    usable: &[usize],
    training: Option<ndarray::ArrayView2<f32>>,
    settings: &AmplifySettings,
    progress: &dyn Progress,
) -> Result<Vec<usize>> {
    match settings.dictionary {
        DictionaryChoice::Complete => Ok(usable.to_vec()),
        DictionaryChoice::Learned {
            n_atoms,
            iterations,
        } => {
            if usable.len() < n_atoms {
                return Err(LearnError::NotEnough {
                    what: "exemplar candidate patches for the learned dictionary",
                    needed: n_atoms,
                    got: usable.len(),
                });
            }
            let cands = cand.low.select(ndarray::Axis(0), usable);
            let k = cands.ncols();
            let t = match training {
                Some(t) if t.ncols() != k => {
                    return Err(LearnError::param(
                        "training",
                        t.ncols(),
                        "dimension differs from the coarse patch",
                    ));
                }
                Some(t) => t,
                None => cands.slice(ndarray::s![0..0, ..]),
            };
            // The training signals then the candidates, sampled down to `max_training` rows
            // (the picked rows are gathered; the pool itself is never copied).
            let n_all = t.nrows() + cands.nrows();
            let pick: Vec<usize> = if n_all > settings.max_training {
                let mut rng = Pcg64Mcg::seed_from_u64(item_seed(settings.seed, 0x7a, n_all as u64));
                let mut pick = sample(&mut rng, n_all, settings.max_training).into_vec();
                pick.sort_unstable();
                pick
            } else {
                (0..n_all).collect()
            };
            let mut train_rows: Vec<f32> = Vec::with_capacity(pick.len() * k);
            for &i in &pick {
                let row = if i < t.nrows() {
                    t.row(i)
                } else {
                    cands.row(i - t.nrows())
                };
                train_rows.extend(row.iter().copied());
            }
            let train = Array2::from_shape_vec((pick.len(), k), train_rows)
                .map_err(|_| LearnError::param("training", k, "internal shape error"))?;
            let learned = constrained_learning(
                train.view(),
                cands.view(),
                &ConstrainedSettings {
                    n_atoms,
                    sparsity: settings.sparsity.min(n_atoms),
                    iterations,
                    seed: settings.seed,
                },
                progress,
            )?;
            Ok(learned.sources.iter().map(|&s| usable[s]).collect())
        }
    }
}
