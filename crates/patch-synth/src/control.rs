//! The control structures of section 3.1 (output size, guide, categorisation map) and the
//! categories a grid window allows.

use relief_heightfield::Heightfield;

use crate::category::{ANY_CATEGORY, CategoryMap};
use crate::error::{PatchSynthError, Result};
use crate::grid::MAX_OUTPUT_CELLS;
use crate::index::ExemplarIndex;

/// The control structures of section 3.1: output size, optional guide and optional
/// categorisation map (both at the target resolution).
#[derive(Debug, Clone)]
pub struct Control {
    /// Output width in cells.
    pub width: usize,
    /// Output height in cells.
    pub height: usize,
    /// Low-frequency guide, `width x height` (see [`crate::guide`]); `None` = unguided.
    pub guide: Option<Heightfield>,
    /// Categorisation map, `width x height`; `None` = every category everywhere.
    pub categories: Option<CategoryMap>,
}

impl Control {
    /// Guided synthesis at the guide's size, every category allowed.
    pub fn guided(guide: Heightfield) -> Self {
        Self {
            width: guide.width(),
            height: guide.height(),
            guide: Some(guide),
            categories: None,
        }
    }
    /// Unguided synthesis of `width x height` cells.
    pub fn unguided(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            guide: None,
            categories: None,
        }
    }
    /// The same control with a categorisation map.
    pub fn with_categories(mut self, map: CategoryMap) -> Self {
        self.categories = Some(map);
        self
    }

    pub(crate) fn check(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(PatchSynthError::InvalidControl {
                name: "size",
                reason: format!("{} x {} is empty", self.width, self.height),
            });
        }
        if self
            .width
            .checked_mul(self.height)
            .is_none_or(|n| n > MAX_OUTPUT_CELLS)
        {
            return Err(PatchSynthError::InvalidControl {
                name: "size",
                reason: format!(
                    "{} x {} exceeds the {MAX_OUTPUT_CELLS} cells a synthesis may produce",
                    self.width, self.height
                ),
            });
        }
        if let Some(g) = &self.guide {
            if (g.width(), g.height()) != (self.width, self.height) {
                return Err(PatchSynthError::InvalidControl {
                    name: "guide",
                    reason: format!(
                        "guide is {} x {} but the output is {} x {}",
                        g.width(),
                        g.height(),
                        self.width,
                        self.height
                    ),
                });
            }
            if g.as_slice().iter().any(|v| !v.is_finite()) {
                return Err(PatchSynthError::InvalidControl {
                    name: "guide",
                    reason: format!("{} void/non-finite cells; fill them first", g.void_count()),
                });
            }
        }
        if let Some(m) = &self.categories
            && (m.width, m.height) != (self.width, self.height)
        {
            {
                return Err(PatchSynthError::InvalidControl {
                    name: "categories",
                    reason: format!(
                        "map is {} x {} but the output is {} x {}",
                        m.width, m.height, self.width, self.height
                    ),
                });
            }
        }
        Ok(())
    }
}

/// Allowed category flags (indexed like `index.categories`) over a window of the padded map.
pub(crate) fn allowed_categories(
    index: &ExemplarIndex,
    map: Option<&[u16]>,
    cw: usize,
    x0: usize,
    y0: usize,
    p: usize,
) -> Vec<bool> {
    let cats = &index.categories;
    let Some(map) = map else {
        return vec![true; cats.len()];
    };
    let mut allowed = vec![false; cats.len()];
    for y in y0..y0 + p {
        for &id in &map[y * cw + x0..y * cw + x0 + p] {
            if id == ANY_CATEGORY {
                return vec![true; cats.len()];
            }
            if let Ok(i) = cats.binary_search(&id) {
                allowed[i] = true;
            }
        }
    }
    allowed
}
