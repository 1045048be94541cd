//! The exemplar-detail step of sketch synthesis ([`AmplifySettings::exemplar_detail`]): the
//! bicubic interpolation of the step's input plus each primitive's atom detail at the
//! exemplar's own amplitude, and the exemplar's octave ratio and x4 detail RMS that scale it
//! (also used by the structure step and the amplification planner).

use rayon::prelude::*;
use relief_sparse_core::Patches;
use relief_sparse_core::dictionary::Atom;

use super::*;

/// Ratio of an exemplar's detail amplitude one x4 octave coarser to its own (RMS of the grid
/// minus its x4 reduction up-sampled back, on the exemplar reduced x4 vs on the exemplar):
/// how much larger the detail of a step is than the exemplar's when the step relies on
/// self-similarity ([`AmplifySettings::exemplar_detail`]). Clamped to `[1, 4]` (4: relief
/// proportional to scale); 2 when the exemplar is too small to measure it.
pub(crate) fn octave_ratio(exemplar: &Heightfield) -> f64 {
    let detail = x4_detail_rms;
    let (w, h) = (exemplar.width(), exemplar.height());
    if w.min(h) < 128 {
        return 2.0;
    }
    let measured = exemplar
        .resample(w / 4, h / 4)
        .ok()
        .and_then(|e1| Some(detail(&e1)? / detail(exemplar)?));
    match measured {
        Some(r) if r.is_finite() => r.clamp(1.0, 4.0),
        _ => 2.0,
    }
}

/// Number of best-matching atoms a primitive's exemplar detail is picked from.
const DETAIL_CHOICES: usize = 8;

/// RMS (metres) of a grid's x4 detail: the grid minus its x4 reduction up-sampled back
/// (`None` below 16 x 16 cells).
pub(crate) fn x4_detail_rms(e: &Heightfield) -> Option<f64> {
    let (w, h) = (e.width() / 4 * 4, e.height() / 4 * 4);
    if w.min(h) < 16 {
        return None;
    }
    let e = e.crop(0, 0, w, h).ok()?;
    let back = e.resample(w / 4, h / 4).ok()?.resample(w, h).ok()?;
    let s: f64 = e
        .as_slice()
        .iter()
        .zip(back.as_slice())
        .map(|(a, b)| (*a as f64 - *b as f64).powi(2))
        .sum();
    Some((s / (w * h) as f64).sqrt())
}

impl MultiResDictionary {
    /// One x4 step of [`AmplifySettings::exemplar_detail`]: the bicubic interpolation of the
    /// input plus, for every primitive, the detail `D_j = H_j - up(L_j)` of its atom at the
    /// exemplar's amplitude (metres, scaled to [`MultiResDictionary::detail_rms`]) with the sign
    /// of its correlation with the input patch; the atom is one of the best-matching ones
    /// (seeded), so a smooth input does not repeat one detail on the grid.
    pub(crate) fn exemplar_detail_step(
        &self,
        coarse: &Heightfield,
        patches: &Patches,
        fine: CentreGrid,
        settings: &AmplifySettings,
    ) -> Result<Sct> {
        let a = settings.patch_size();
        let ah = STEP_FACTOR * a;
        let f = STEP_FACTOR as f64;
        let mut detail = Dictionary::new(ah, 1.0, settings.radius * f)?;
        let mask = detail.support_mask().to_vec();
        // The detail gain baked into the atoms (normalize_detail) restores the variance the
        // blend loses; the blended detail has the RMS of the atoms' details without it.
        let gmap = settings
            .normalize_detail
            .then(|| detail_gain(ah, f * settings.grid_step(), f * settings.radius));
        let support = mask.iter().filter(|m| **m).count().max(1) as f64;
        // Detail atom index, amplitude (metres) and per-sample RMS without the gain of every
        // dictionary atom.
        let mut slot: Vec<Option<(u32, f32, f64)>> = Vec::with_capacity(self.len());
        for (j, atom) in self.high.atoms().iter().enumerate() {
            let Atom::Data(vh) = atom else {
                return Err(LearnError::param(
                    "dictionary",
                    j,
                    "exemplar detail needs data atoms",
                ));
            };
            let low: Vec<f64> = self.low.row(j).iter().map(|&v| v as f64).collect();
            let up = upsample4(&low, a);
            let (l, tr) = (self.low_norm[j] as f64, self.transfer[j] as f64);
            let mut d: Vec<f64> = vh
                .iter()
                .zip(&up)
                .map(|(&h, &u)| l * (tr * h as f64 - u))
                .collect();
            let (sum, cnt) = d
                .iter()
                .zip(&mask)
                .filter(|(_, m)| **m)
                .fold((0.0, 0usize), |(s, c), (v, _)| (s + v, c + 1));
            let mean = sum / cnt.max(1) as f64;
            d.iter_mut().for_each(|v| *v -= mean);
            let norm = d
                .iter()
                .zip(&mask)
                .filter(|(_, m)| **m)
                .map(|(v, _)| v * v)
                .sum::<f64>()
                .sqrt();
            let raw = d
                .iter()
                .zip(&mask)
                .enumerate()
                .filter(|(_, (_, m))| **m)
                .map(|(i, (v, _))| (v / gmap.as_ref().map_or(1.0, |g| g[i])).powi(2))
                .sum::<f64>();
            let row: Vec<f32> = d.iter().map(|&v| v as f32).collect();
            slot.push(match detail.push_data(&row) {
                Ok(k) => Some((k as u32, norm as f32, (raw / support).sqrt())),
                Err(relief_sparse_core::SparseError::DegenerateAtom { .. }) => None,
                Err(e) => return Err(e.into()),
            });
        }
        if detail.is_empty() {
            let mut v = vec![0f32; ah * ah];
            v[0] = 1.0;
            detail.push_data(&v)?;
        }
        // Each primitive's detail atom: one of the best-matching atoms (at most
        // DETAIL_CHOICES, |correlation| >= half the best), picked by a seeded hash of the
        // primitive. A smooth input matches many atoms almost equally; always taking the best
        // one repeats the same detail on the grid (a wallpaper of one landform).
        let n = patches.matrix.nrows();
        // Strongest first, ties by atom: a total order, so sorting only the first
        // DETAIL_CHOICES after a selection gives the same list as sorting them all.
        let order = |x: &(f32, usize), y: &(f32, usize)| {
            y.0.abs().total_cmp(&x.0.abs()).then(x.1.cmp(&y.1))
        };
        let picks: Vec<Option<(u32, f32, f64)>> = (0..n)
            .into_par_iter()
            .map_init(Vec::new, |best: &mut Vec<(f32, usize)>, i| {
                let p = patches.matrix.row(i);
                best.clear();
                best.extend(
                    self.low
                        .outer_iter()
                        .enumerate()
                        .filter(|(j, _)| slot[*j].is_some())
                        .map(|(j, l)| (p.dot(&l), j)),
                );
                if best.len() > DETAIL_CHOICES {
                    best.select_nth_unstable_by(DETAIL_CHOICES - 1, order);
                    best.truncate(DETAIL_CHOICES);
                }
                best.sort_unstable_by(order);
                let top = best.first()?.0.abs();
                let k = best
                    .iter()
                    .take(DETAIL_CHOICES)
                    .take_while(|(c, _)| c.abs() >= 0.5 * top)
                    .count()
                    .max(1);
                let (c, j) = best[(item_seed(settings.seed, 0xde7a, i as u64) % k as u64) as usize];
                let (atom, amp, rms) = slot[j]?;
                Some((atom, if c < 0.0 { -amp } else { amp }, rms))
            })
            .collect();
        // The learned atoms are not a fair sample of the exemplar's detail (constrained learning
        // favours atoms that code the smooth input well): the amplitudes are scaled so the
        // per-sample RMS of the picked details is the exemplar's at this step's scale.
        let (e2, used) = picks
            .iter()
            .flatten()
            .fold((0.0f64, 0usize), |(s, c), (_, _, r)| (s + r * r, c + 1));
        let gain = match self.detail_rms {
            Some(target) if used > 0 && e2 > 0.0 => target / (e2 / used as f64).sqrt(),
            _ => 1.0,
        };
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let (mut atoms, mut coeffs) = (Vec::new(), Vec::new());
        for pick in picks {
            if let Some((atom, amp, _)) = pick {
                atoms.push(atom);
                coeffs.push((amp as f64 * gain) as f32);
            }
            offsets.push(atoms.len() as u32);
        }
        let layer = SparseLayer::from_parts(
            Arc::new(detail),
            Placement::Grid(fine),
            vec![0.0; n],
            offsets,
            atoms,
            coeffs,
        )?;
        let low = interpolation_layer(coarse, settings)?;
        let (cx, cy) = coarse.cell_size();
        Ok(Sct::new(
            Node::Add(vec![Node::Layer(low), Node::Layer(layer)]),
            coarse.width() * STEP_FACTOR,
            coarse.height() * STEP_FACTOR,
            (cx / f, cy / f),
        )?)
    }
}
