//! Checks shared by the fuzz targets: a reader may return `Err`, never panic, and an `Ok` raster
//! must satisfy the invariants relief-io documents.

use std::path::Path;

use relief_io::{Raster, ReadOptions, Result};

/// Options of every target: a cell limit of 4 M cells (16 MiB of f32) so a compressed file that
/// declares a huge size is refused by the limit, not by libFuzzer's malloc limit.
pub fn opts() -> ReadOptions {
    ReadOptions {
        max_cells: 1 << 22,
        ..Default::default()
    }
}

/// Asserts the invariants of a successful read; an error must have a message.
pub fn check(res: Result<Raster>, opts: &ReadOptions) -> Option<Raster> {
    match res {
        Ok(r) => {
            let hf = &r.heightfield;
            assert!(hf.width() > 0 && hf.height() > 0);
            assert_eq!(hf.width() * hf.height(), hf.as_slice().len());
            assert!(hf.len() <= opts.max_cells, "cell limit ignored");
            assert!(
                hf.as_slice().iter().all(|v| !v.is_infinite()),
                "infinite sample"
            );
            assert!(
                hf.as_slice().iter().any(|v| v.is_finite()),
                "all-void raster accepted"
            );
            let (cx, cy) = hf.cell_size();
            assert!(cx > 0.0 && cy > 0.0 && cx.is_finite() && cy.is_finite());
            Some(r)
        }
        Err(e) => {
            assert!(!e.to_string().is_empty());
            None
        }
    }
}

/// Reads `data` as if it were a file called `name` (the extension is the format hint).
pub fn read_as(data: &[u8], name: &str) -> Option<Raster> {
    let o = opts();
    check(relief_io::read_bytes(data, Some(Path::new(name)), &o), &o)
}

/// Raw readers: the first two bytes give the width (0 = square), the rest is the file.
pub fn read_raw(data: &[u8], name: &str) {
    if data.len() < 2 {
        return;
    }
    let w = u16::from_le_bytes([data[0], data[1]]) as usize;
    let o = ReadOptions {
        width: (w > 0).then_some(w),
        ..opts()
    };
    check(
        relief_io::read_bytes(&data[2..], Some(Path::new(name)), &o),
        &o,
    );
}

/// A function atom for the `.sct` target: `1 - |sin(freq * t)|` along direction `angle`.
#[derive(Debug)]
pub struct Ridge {
    /// Frequency.
    pub freq: f64,
    /// Direction in radians.
    pub angle: f64,
}

impl relief_sparse_core::FunctionAtom for Ridge {
    fn eval(&self, u: f64, v: f64) -> f64 {
        let t = u * self.angle.cos() + v * self.angle.sin();
        1.0 - (self.freq * t).sin().abs()
    }
    fn descriptor(&self) -> relief_sparse_core::AtomDescriptor {
        relief_sparse_core::AtomDescriptor {
            kind: "ridge".into(),
            params: vec![self.freq, self.angle],
        }
    }
}

/// The registry of the `.sct` target: `ridge` (two parameters) and the noise atoms of
/// relief-dictionary-learning (`relief fit-procedural` models).
pub fn sct_registry() -> relief_sparse_core::FunctionAtomRegistry {
    let mut r = relief_sparse_core::FunctionAtomRegistry::new();
    r.register("ridge", |p: &[f64]| {
        if p.len() != 2 || !p.iter().all(|x| x.is_finite()) {
            return Err(relief_sparse_core::SparseError::param(
                "ridge params",
                p.len(),
                "need 2 finite values",
            ));
        }
        Ok(std::sync::Arc::new(Ridge {
            freq: p[0],
            angle: p[1],
        })
            as std::sync::Arc<dyn relief_sparse_core::FunctionAtom>)
    });
    relief_dictionary_learning::noise::register_function_atoms(&mut r);
    r
}

/// A `width x height` tree of one constant `value` (1 m cells): the layer every name of a
/// fuzzed tree description resolves to.
pub fn constant_tree(
    width: usize,
    height: usize,
    value: f64,
) -> relief_sparse_core::Result<relief_sparse_core::Sct> {
    relief_sparse_core::Sct::new(
        relief_sparse_core::Node::Constant(value),
        width,
        height,
        (1.0, 1.0),
    )
}
