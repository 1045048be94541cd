// The lifting constants are quoted with the precision they are published with.
#![allow(clippy::excessive_precision)]

//! The four lifting schemes and their normalisation.

use serde::{Deserialize, Serialize};

use crate::error::{Result, WaveletError};

/// A wavelet basis, implemented by lifting (Daubechies and Sweldens 1998).
///
/// Normalisation ("metric"): the low-pass has DC gain 1 in 1-D, so approximations stay in
/// metres (a level of approximation is a smoothed, half-resolution terrain), and the detail
/// coefficients are elevation increments. Against PyWavelets (which uses unit-norm filters),
/// with `cA`, `cD` the 1-D single-level coefficients of the matching PyWavelets wavelet:
/// `low = cA / sqrt(2)` and `high = -sqrt(2) * cD`, for every basis here. In 2-D one level
/// therefore gives `LL = cA / 2`, `H = -cH`, `V = -cV`, `D = 2 cD`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Wavelet {
    /// Haar (PyWavelets `haar`): `d = x_odd - x_even`, `s = x_even + d / 2`.
    Haar,
    /// Linear spline, CDF 5/3 (PyWavelets `bior2.2`; the paper's recommended base):
    /// `d = x_odd - (s_l + s_r) / 2`, `s = x_even + (d_l + d_r) / 4`.
    Cdf53,
    /// CDF 9/7 (PyWavelets `bior4.4`), four lifting steps and a scaling.
    Cdf97,
    /// Daubechies 4-tap, two vanishing moments (PyWavelets `db2`), three lifting steps and a
    /// scaling.
    Db4,
}

impl Wavelet {
    /// Every supported basis.
    pub const ALL: [Wavelet; 4] = [Wavelet::Haar, Wavelet::Cdf53, Wavelet::Cdf97, Wavelet::Db4];

    /// Short name (`haar`, `cdf53`, `cdf97`, `db4`), accepted by [`Wavelet::from_name`].
    pub fn name(self) -> &'static str {
        match self {
            Wavelet::Haar => "haar",
            Wavelet::Cdf53 => "cdf53",
            Wavelet::Cdf97 => "cdf97",
            Wavelet::Db4 => "db4",
        }
    }

    /// The name of the PyWavelets wavelet with the same filters (up to the normalisation
    /// documented on [`Wavelet`]).
    pub fn pywt_name(self) -> &'static str {
        match self {
            Wavelet::Haar => "haar",
            Wavelet::Cdf53 => "bior2.2",
            Wavelet::Cdf97 => "bior4.4",
            Wavelet::Db4 => "db2",
        }
    }

    /// Parses a name: the short names above, PyWavelets names, and a few aliases
    /// (`linear`, `linear-spline`, `5/3`, `9/7`, `d4`, `daub4`).
    pub fn from_name(name: &str) -> Result<Self> {
        let n = name.trim().to_ascii_lowercase();
        Ok(match n.as_str() {
            "haar" | "db1" => Wavelet::Haar,
            "cdf53" | "cdf5/3" | "5/3" | "bior2.2" | "linear" | "linear-spline" | "spline" => {
                Wavelet::Cdf53
            }
            "cdf97" | "cdf9/7" | "9/7" | "bior4.4" => Wavelet::Cdf97,
            "db4" | "d4" | "daub4" | "db2" | "daubechies4" => Wavelet::Db4,
            _ => return Err(WaveletError::UnknownWavelet(name.to_string())),
        })
    }

    pub(crate) fn scheme(self) -> &'static Scheme {
        match self {
            Wavelet::Haar => &HAAR,
            Wavelet::Cdf53 => &CDF53,
            Wavelet::Cdf97 => &CDF97,
            Wavelet::Db4 => &DB4,
        }
    }

    /// Margin (in samples of the finer level) that a window of one inverse level needs on each
    /// side so that its values are exact: every lifting step reaches at most one lane sample
    /// (two interleaved samples) further.
    pub fn synthesis_margin(self) -> usize {
        2 * self.scheme().steps.len() + 2
    }
}

impl std::fmt::Display for Wavelet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Which lane a lifting step updates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Lane {
    /// Even samples (becoming the low-pass).
    Even,
    /// Odd samples (becoming the high-pass).
    Odd,
}

/// One lifting step: `target[i] += sum_k coef_k * other[i + offset_k]`.
#[derive(Debug)]
pub(crate) struct Step {
    pub(crate) target: Lane,
    pub(crate) taps: &'static [(isize, f32)],
}

/// A lifting scheme: steps in analysis order, then a scaling of both lanes.
#[derive(Debug)]
pub(crate) struct Scheme {
    pub(crate) steps: &'static [Step],
    pub(crate) scale_even: f32,
    pub(crate) scale_odd: f32,
}

static HAAR: Scheme = Scheme {
    steps: &[
        Step {
            target: Lane::Odd,
            taps: &[(0, -1.0)],
        },
        Step {
            target: Lane::Even,
            taps: &[(0, 0.5)],
        },
    ],
    scale_even: 1.0,
    scale_odd: 1.0,
};

static CDF53: Scheme = Scheme {
    steps: &[
        Step {
            target: Lane::Odd,
            taps: &[(0, -0.5), (1, -0.5)],
        },
        Step {
            target: Lane::Even,
            taps: &[(-1, 0.25), (0, 0.25)],
        },
    ],
    scale_even: 1.0,
    scale_odd: 1.0,
};

// Daubechies-Sweldens factorisation of the CDF 9/7 pair (JPEG 2000 irreversible transform).
const A97: f32 = -1.586_134_342_059_924;
const B97: f32 = -0.052_980_118_572_961;
const G97: f32 = 0.882_911_075_530_934;
const D97: f32 = 0.443_506_852_043_971;
const K97: f64 = 1.230_174_104_914_001;

static CDF97: Scheme = Scheme {
    steps: &[
        Step {
            target: Lane::Odd,
            taps: &[(0, A97), (1, A97)],
        },
        Step {
            target: Lane::Even,
            taps: &[(-1, B97), (0, B97)],
        },
        Step {
            target: Lane::Odd,
            taps: &[(0, G97), (1, G97)],
        },
        Step {
            target: Lane::Even,
            taps: &[(-1, D97), (0, D97)],
        },
    ],
    scale_even: (1.0 / K97) as f32,
    scale_odd: K97 as f32,
};

// Factorisation of the polyphase matrix of PyWavelets' db2 (periodization phase):
// o -= e[i+1] / sqrt3; e += (6 - 3 sqrt3)/4 o[i] + sqrt3/4 o[i-1]; o -= e / 3;
// then e *= (sqrt3 + 1)/sqrt6 and o *= sqrt6/(sqrt3 + 1) give PyWavelets' cA, cD exactly.
// The metric normalisation divides e by sqrt2 and multiplies o by -sqrt2.
static DB4: Scheme = Scheme {
    steps: &[
        Step {
            target: Lane::Odd,
            taps: &[(1, -0.577_350_269_189_625_8)],
        },
        Step {
            target: Lane::Even,
            taps: &[(-1, 0.433_012_701_892_219_3), (0, 0.200_961_894_323_341_94)],
        },
        Step {
            target: Lane::Odd,
            taps: &[(0, -1.0 / 3.0)],
        },
    ],
    // (sqrt3 + 1) / (2 sqrt3) and -(3 - sqrt3).
    scale_even: 0.788_675_134_594_812_9,
    scale_odd: -1.267_949_192_431_122_8,
};
