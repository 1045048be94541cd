//! What the input validation (section 4) reports: per guide block, per exemplar, and the
//! outcome with its set cover and suggestion. Plain data, so the error type can carry it.

/// Candidate count of one guide block.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockReport {
    /// Grid column.
    pub gx: usize,
    /// Grid row.
    pub gy: usize,
    /// Output column of the block's top-left cell.
    pub x: usize,
    /// Output row of the block's top-left cell.
    pub y: usize,
    /// Matching patches over all exemplars.
    pub candidates: usize,
    /// Matching patches per exemplar.
    pub per_exemplar: Vec<usize>,
    /// Smallest and largest `N x N` block mean of the guide over this block (metres): the
    /// height range the block needs.
    pub guide_range: (f32, f32),
}

/// Compatibility of one exemplar with the others (synthesis without a guide).
#[derive(Debug, Clone, PartialEq)]
pub struct ExemplarCompatibility {
    /// Exemplar index.
    pub exemplar: usize,
    /// Patches checked (a grid of step `overlap`).
    pub checked: usize,
    /// Of those, patches with at least one matching patch in another exemplar.
    pub compatible: usize,
    /// `compatible / checked` times the exemplar's patch count.
    pub estimated_compatible: usize,
    /// `estimated_compatible >= min_candidates`.
    pub ok: bool,
}

/// Outcome of [`validate`].
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationReport {
    /// True when every block has enough candidates (guided) or every exemplar is compatible
    /// (unguided).
    pub ok: bool,
    /// Required candidates per block.
    pub min_candidates: usize,
    /// RMS tolerance (metres) of the block-descriptor match.
    pub tolerance: f32,
    /// Synthesis grid (columns, rows).
    pub grid: (usize, usize),
    /// One report per guide block, raster order (empty without a guide).
    pub blocks: Vec<BlockReport>,
    /// Indices into `blocks` of the blocks with fewer than `min_candidates` candidates.
    pub failing: Vec<usize>,
    /// Merged guide height ranges (metres) of the failing blocks: heights the exemplars miss.
    pub missing_ranges: Vec<(f32, f32)>,
    /// Range of the patch descriptor means of every exemplar (metres).
    pub exemplar_ranges: Vec<(f32, f32)>,
    /// Greedy set cover: a small subset of exemplars (in pick order) that together give every
    /// coverable block `min_candidates` candidates.
    pub cover: Vec<usize>,
    /// Blocks `(gx, gy)` the whole set cannot cover.
    pub uncovered: Vec<(usize, usize)>,
    /// Exemplar compatibility (unguided validation only).
    pub compatibility: Vec<ExemplarCompatibility>,
    /// What would make a failing validation pass (set by the job layer, e.g. a guide height
    /// mapping that passes), printed after the report.
    pub suggestion: Option<String>,
}

impl std::fmt::Display for ValidationReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if !self.blocks.is_empty() {
            write!(
                f,
                "{} of {} guide blocks have fewer than {} candidate patches (tolerance {:.1} m)",
                self.failing.len(),
                self.blocks.len(),
                self.min_candidates,
                self.tolerance
            )?;
            for &i in self.failing.iter().take(12) {
                let b = &self.blocks[i];
                write!(
                    f,
                    "; block ({}, {}) at x={} y={}: {} candidates, needs heights {:.0}..{:.0} m",
                    b.gx, b.gy, b.x, b.y, b.candidates, b.guide_range.0, b.guide_range.1
                )?;
            }
            if self.failing.len() > 12 {
                write!(f, "; ... {} more", self.failing.len() - 12)?;
            }
            if !self.missing_ranges.is_empty() {
                let r: Vec<String> = self
                    .missing_ranges
                    .iter()
                    .map(|(a, b)| format!("{a:.0}..{b:.0} m"))
                    .collect();
                write!(f, "; missing height ranges: {}", r.join(", "))?;
            }
            let e: Vec<String> = self
                .exemplar_ranges
                .iter()
                .enumerate()
                .map(|(i, (a, b))| format!("#{i} {a:.0}..{b:.0} m"))
                .collect();
            write!(f, "; exemplars cover {}", e.join(", "))?;
        } else {
            let bad: Vec<String> = self
                .compatibility
                .iter()
                .filter(|c| !c.ok)
                .map(|c| {
                    format!(
                        "exemplar {} has ~{} compatible patches",
                        c.exemplar, c.estimated_compatible
                    )
                })
                .collect();
            write!(
                f,
                "exemplar compatibility (need {} patches matching other exemplars): {}",
                self.min_candidates,
                if bad.is_empty() {
                    "ok".to_string()
                } else {
                    bad.join("; ")
                }
            )?;
        }
        if let Some(h) = &self.suggestion {
            write!(f, "; {h}")?;
        }
        Ok(())
    }
}
