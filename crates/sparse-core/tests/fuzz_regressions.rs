//! Regression inputs found by fuzzing `Sct::from_bytes` (+ re-encode + rasterise), the
//! `fuzz/fuzz_targets/sct.rs` target: each file in `tests/fuzz_regressions/` once made the
//! decoder or the rasteriser overflow (huge centres, tiny spacings). They must now decode to an
//! error, or to a tree that re-encodes identically and rasterises without panicking.

use std::sync::Arc;

use relief_sparse_core::dictionary::{AtomDescriptor, FunctionAtom};
use relief_sparse_core::{FunctionAtomRegistry, RasterSettings, Sct, SparseError};

#[derive(Debug)]
struct Ridge {
    freq: f64,
    angle: f64,
}

impl FunctionAtom for Ridge {
    fn eval(&self, u: f64, v: f64) -> f64 {
        let t = u * self.angle.cos() + v * self.angle.sin();
        1.0 - (self.freq * t).sin().abs()
    }
    fn descriptor(&self) -> AtomDescriptor {
        AtomDescriptor {
            kind: "ridge".into(),
            params: vec![self.freq, self.angle],
        }
    }
}

/// The fuzz target's registry (one `ridge` kind).
fn registry() -> FunctionAtomRegistry {
    let mut r = FunctionAtomRegistry::new();
    r.register("ridge", |p: &[f64]| {
        if p.len() != 2 || !p.iter().all(|x| x.is_finite()) {
            return Err(SparseError::param("ridge params", p.len(), "need 2 finite"));
        }
        Ok(Arc::new(Ridge {
            freq: p[0],
            angle: p[1],
        }) as Arc<dyn FunctionAtom>)
    });
    r
}

#[test]
fn fuzz_crash_inputs_are_handled() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(files.len() >= 16, "{} files", files.len());
    let reg = registry();
    for f in files {
        let data = std::fs::read(&f).unwrap();
        if let Ok(sct) = Sct::from_bytes(&data, &reg) {
            let again = sct.to_bytes().unwrap();
            let back = Sct::from_bytes(&again, &reg).unwrap();
            assert_eq!(back.to_bytes().unwrap(), again, "{}", f.display());
            if sct.width() * sct.height() <= 4096 {
                let _ = sct.rasterize(&RasterSettings::default());
                let _ = sct.rasterize(&RasterSettings {
                    scale: 2.5,
                    window: None,
                });
            }
            let _ = sct.eval(0.5, 0.5);
        }
    }
}
