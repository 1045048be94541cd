//! Dictionaries of terrain atoms (guerin2016 section 4.1): data atoms (a x a sample grids at
//! spacing delta, bicubic between samples) and function atoms (analytic, through the
//! [`FunctionAtom`] trait), mixed freely in one [`Dictionary`] (the paper's figure 14).
//!
//! Every atom is normalised the same way: its mean over the support disk is removed and it is
//! scaled to unit L2 norm over the `a x a` discretisation (the vector OMP works on). A function
//! atom keeps its raw function and the two numbers (mean, scale) of that normalisation, so it is
//! evaluated analytically at any point and any resolution.
//!
//! # Patch frame
//! Sample `(row r, column c)` of an atom sits at the offset
//! `((c - (a - 1) / 2) delta, (r - (a - 1) / 2) delta)` from the primitive centre (x east, y
//! south, in the terrain's cell units). A function atom is evaluated at the patch-local
//! coordinates `u = dx / H`, `v = dy / H` with the half width `H = a delta / 2`, so the samples
//! lie in `(-1, 1)^2`. The support is the disk of radius `R = support_radius`; "the mean over the
//! support" is the mean over the samples whose offset lies strictly inside that disk.

use std::collections::HashMap;
use std::fmt::Debug;
use std::sync::Arc;

use ndarray::{Array2, ArrayView2};

use crate::error::{Result, SparseError};
use crate::patches::{Patches, support_mask};

/// Serialisable description of a function atom: a kind name and its parameters.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AtomDescriptor {
    /// Kind name, the key of the [`FunctionAtomRegistry`] (e.g. `"ridged_noise"`).
    pub kind: String,
    /// Parameters understood by the kind's constructor.
    pub params: Vec<f64>,
}

/// An analytic atom: a function of the patch-local coordinates.
pub trait FunctionAtom: Send + Sync + Debug {
    /// Raw value at patch-local coordinates `(u, v)` in `[-1, 1]^2` (u east, v south). The
    /// dictionary removes the mean and normalises; the raw function need not be normalised.
    fn eval(&self, u: f64, v: f64) -> f64;
    /// Serialisable description (kind name + parameters) used by the `.sct` format.
    fn descriptor(&self) -> AtomDescriptor;
    /// How many leading parameters describe a field that several atoms may share (windows
    /// of one noise field differ only in the remaining ones: offset, angle). Atoms of one kind
    /// with the same leading parameters store them once ([`crate::dictionary_values`]).
    /// Default 0: every parameter is the atom's own.
    fn field_params(&self) -> usize {
        0
    }
}

/// Constructor of a function atom from its parameters.
pub type FunctionAtomConstructor =
    Box<dyn Fn(&[f64]) -> Result<Arc<dyn FunctionAtom>> + Send + Sync>;

/// Kind name -> constructor table used when reading function atoms back from `.sct` bytes.
#[derive(Default)]
pub struct FunctionAtomRegistry {
    map: HashMap<String, FunctionAtomConstructor>,
}

impl Debug for FunctionAtomRegistry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut kinds: Vec<&String> = self.map.keys().collect();
        kinds.sort();
        f.debug_struct("FunctionAtomRegistry")
            .field("kinds", &kinds)
            .finish()
    }
}

impl FunctionAtomRegistry {
    /// An empty registry (enough for dictionaries of data atoms only).
    pub fn new() -> Self {
        Self::default()
    }

    /// Registers (or replaces) the constructor of `kind`.
    pub fn register(
        &mut self,
        kind: impl Into<String>,
        constructor: impl Fn(&[f64]) -> Result<Arc<dyn FunctionAtom>> + Send + Sync + 'static,
    ) {
        self.map.insert(kind.into(), Box::new(constructor));
    }

    /// Builds the atom described by `desc`.
    pub fn construct(&self, desc: &AtomDescriptor) -> Result<Arc<dyn FunctionAtom>> {
        let c = self
            .map
            .get(&desc.kind)
            .ok_or_else(|| SparseError::UnknownFunctionAtom {
                kind: desc.kind.clone(),
            })?;
        c(&desc.params)
    }
}

/// One normalised atom.
#[derive(Debug, Clone)]
pub enum Atom {
    /// A data atom: `a * a` row-major samples, zero mean over the support, unit L2 norm.
    Data(Vec<f32>),
    /// A function atom: `d(p) = (raw(u, v) - mean) * scale`.
    Function {
        /// The raw function.
        func: Arc<dyn FunctionAtom>,
        /// Mean of the raw function over the support samples.
        mean: f64,
        /// `1 / ||raw - mean||_2` over the `a x a` samples.
        scale: f64,
    },
}

/// A dictionary `D` of `N` atoms of dimension `K = a * a`.
#[derive(Debug, Clone)]
pub struct Dictionary {
    patch_size: usize,
    spacing: f64,
    support_radius: f64,
    atoms: Vec<Atom>,
    mask: Vec<bool>,
}

/// Removes the masked mean and normalises to unit norm; `None` for zero energy.
fn normalise(v: &mut [f64], mask: &[bool]) -> Option<(f64, f64)> {
    let (sum, cnt) = v
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .fold((0.0, 0usize), |(s, c), (x, _)| (s + x, c + 1));
    let mean = sum / cnt as f64;
    v.iter_mut().for_each(|x| *x -= mean);
    let n2: f64 = v.iter().map(|x| x * x).sum();
    let max = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if !(n2.is_finite()) || n2 <= 0.0 || n2.sqrt() <= 1e-9 * max.max(mean.abs()).max(1e-30) {
        return None;
    }
    let scale = 1.0 / n2.sqrt();
    v.iter_mut().for_each(|x| *x *= scale);
    Some((mean, scale))
}

impl Dictionary {
    /// An empty dictionary for `a x a` atoms at spacing `delta` with support radius `R`.
    pub fn new(patch_size: usize, spacing: f64, support_radius: f64) -> Result<Self> {
        let mask = support_mask(patch_size, spacing, support_radius)?;
        Ok(Self {
            patch_size,
            spacing,
            support_radius,
            atoms: Vec::new(),
            mask,
        })
    }

    /// Side `a` of the atoms in samples.
    pub fn patch_size(&self) -> usize {
        self.patch_size
    }

    /// Atom dimension `K = a * a`.
    pub fn dim(&self) -> usize {
        self.patch_size * self.patch_size
    }

    /// Sample spacing `delta` of the atoms (terrain cell units).
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Support radius `R` (terrain cell units).
    pub fn support_radius(&self) -> f64 {
        self.support_radius
    }

    /// Number of atoms `N`.
    pub fn len(&self) -> usize {
        self.atoms.len()
    }

    /// True when the dictionary holds no atom.
    pub fn is_empty(&self) -> bool {
        self.atoms.is_empty()
    }

    /// The atoms.
    pub fn atoms(&self) -> &[Atom] {
        &self.atoms
    }

    /// Support mask of the `a x a` samples (row-major): samples strictly inside the disk.
    pub fn support_mask(&self) -> &[bool] {
        &self.mask
    }

    /// Adds a data atom from `a * a` raw row-major samples (normalised here). Returns its index.
    pub fn push_data(&mut self, samples: &[f32]) -> Result<usize> {
        if samples.len() != self.dim() {
            return Err(SparseError::DimensionMismatch {
                what: "data atom samples",
                expected: self.dim(),
                got: samples.len(),
            });
        }
        if samples.iter().any(|v| !v.is_finite()) {
            return Err(SparseError::non_finite("data atom", self.atoms.len()));
        }
        let mut v: Vec<f64> = samples.iter().map(|&x| x as f64).collect();
        normalise(&mut v, &self.mask).ok_or(SparseError::DegenerateAtom {
            atom: self.atoms.len(),
        })?;
        self.atoms
            .push(Atom::Data(v.iter().map(|&x| x as f32).collect()));
        Ok(self.atoms.len() - 1)
    }

    /// Adds a function atom (normalised by its discretised mean and norm). Returns its index.
    pub fn push_function(&mut self, func: Arc<dyn FunctionAtom>) -> Result<usize> {
        let mut v = self.discretize_raw(func.as_ref());
        if v.iter().any(|x| !x.is_finite()) {
            return Err(SparseError::non_finite("function atom", self.atoms.len()));
        }
        let (mean, scale) = normalise(&mut v, &self.mask).ok_or(SparseError::DegenerateAtom {
            atom: self.atoms.len(),
        })?;
        self.atoms.push(Atom::Function { func, mean, scale });
        Ok(self.atoms.len() - 1)
    }

    /// Re-adds an already-normalised atom (used by the `.sct` reader).
    pub(crate) fn push_raw(&mut self, atom: Atom) {
        self.atoms.push(atom);
    }

    fn discretize_raw(&self, func: &dyn FunctionAtom) -> Vec<f64> {
        let a = self.patch_size;
        let h = (a as f64 - 1.0) / 2.0;
        let half = a as f64 / 2.0;
        let mut v = Vec::with_capacity(a * a);
        for r in 0..a {
            for c in 0..a {
                v.push(func.eval((c as f64 - h) / half, (r as f64 - h) / half));
            }
        }
        v
    }

    /// A dictionary whose atoms are the rows of `matrix` (`n_atoms x a*a`), each normalised.
    /// A row with no energy after mean removal is an error.
    pub fn from_matrix(
        matrix: ArrayView2<f32>,
        patch_size: usize,
        spacing: f64,
        support_radius: f64,
    ) -> Result<Self> {
        let mut d = Self::new(patch_size, spacing, support_radius)?;
        if matrix.ncols() != d.dim() {
            return Err(SparseError::DimensionMismatch {
                what: "dictionary matrix columns vs patch_size^2",
                expected: d.dim(),
                got: matrix.ncols(),
            });
        }
        for row in matrix.outer_iter() {
            let v: Vec<f32> = row.iter().copied().collect();
            d.push_data(&v)?;
        }
        Ok(d)
    }

    /// A dictionary of the patches `selection` (indices into `patches`; all of them when
    /// `None`: the complete dictionary of section 4.3). Patches with no energy (flat terrain)
    /// cannot be atoms and are skipped; the returned vector maps atom index -> patch index.
    pub fn from_patches(
        patches: &Patches,
        selection: Option<&[usize]>,
    ) -> Result<(Self, Vec<usize>)> {
        let g = &patches.geometry;
        let mut d = Self::new(g.patch_size, g.spacing, g.support_radius)?;
        let n = patches.matrix.nrows();
        let all: Vec<usize>;
        let sel = match selection {
            Some(s) => s,
            None => {
                all = (0..n).collect();
                &all
            }
        };
        let mut map = Vec::with_capacity(sel.len());
        for &i in sel {
            if i >= n {
                return Err(SparseError::param(
                    "selection",
                    i,
                    "patch index out of range",
                ));
            }
            let row: Vec<f32> = patches.matrix.row(i).iter().copied().collect();
            match d.push_data(&row) {
                Ok(_) => map.push(i),
                Err(SparseError::DegenerateAtom { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        Ok((d, map))
    }

    /// The `N x K` matrix of the discretised, normalised atoms (one atom per row) for OMP.
    pub fn discretize(&self) -> Array2<f32> {
        let k = self.dim();
        let mut m = Array2::zeros((self.atoms.len(), k));
        for (i, atom) in self.atoms.iter().enumerate() {
            let mut row = m.row_mut(i);
            match atom {
                Atom::Data(v) => row.iter_mut().zip(v).for_each(|(o, &x)| *o = x),
                Atom::Function { func, mean, scale } => {
                    let raw = self.discretize_raw(func.as_ref());
                    row.iter_mut()
                        .zip(raw)
                        .for_each(|(o, x)| *o = ((x - mean) * scale) as f32);
                }
            }
        }
        m
    }

    /// Value of normalised function atom `atom` at the offset `(dx, dy)` from the centre;
    /// `None` for a data atom.
    pub fn eval_function(&self, atom: usize, dx: f64, dy: f64) -> Option<f64> {
        match self.atoms.get(atom)? {
            Atom::Function { func, mean, scale } => {
                let half = self.patch_size as f64 * self.spacing / 2.0;
                Some((func.eval(dx / half, dy / half) - mean) * scale)
            }
            Atom::Data(_) => None,
        }
    }

    /// True when every atom is a data atom.
    pub fn is_data_only(&self) -> bool {
        self.atoms.iter().all(|a| matches!(a, Atom::Data(_)))
    }
}
