//! The stand-alone dictionary stream (`Dictionary::to_bytes/from_bytes`, used by `relief learn`
//! and `relief compress --dictionary`): exact round trip on real DEM patches, mixed with
//! function atoms, and defensive reading of truncated, corrupt and hostile bytes.

use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use relief_sparse_core::dictionary::{AtomDescriptor, FunctionAtom};
use relief_sparse_core::format::DICTIONARY_MAGIC;
use relief_sparse_core::{
    Dictionary, EncodeSettings, FunctionAtomRegistry, PatchGeometry, RasterSettings, SparseError,
    encode, extract_patches,
};

#[derive(Debug)]
struct Wave {
    freq: f64,
}

impl FunctionAtom for Wave {
    fn eval(&self, u: f64, v: f64) -> f64 {
        (self.freq * (u + 0.5 * v)).sin()
    }
    fn descriptor(&self) -> AtomDescriptor {
        AtomDescriptor {
            kind: "wave".into(),
            params: vec![self.freq],
        }
    }
}

fn registry() -> FunctionAtomRegistry {
    let mut r = FunctionAtomRegistry::new();
    r.register("wave", |p: &[f64]| {
        if p.len() != 1 || !p[0].is_finite() {
            return Err(SparseError::param("wave params", p.len(), "need 1 finite"));
        }
        Ok(Arc::new(Wave { freq: p[0] }) as Arc<dyn FunctionAtom>)
    });
    r
}

#[test]
fn round_trip_is_exact_and_encodes_identically() {
    let Some(hf) = relief_testdata::dem_crop("grandcanyon", 120, 260, 64, 56) else {
        return;
    };
    let p = extract_patches(&hf, &PatchGeometry::with_patch_size(8)).unwrap();
    let sel: Vec<usize> = (0..40).map(|k| k * 3 + 1).collect();
    let (mut dict, _) = Dictionary::from_patches(&p, Some(&sel)).unwrap();
    for k in 1..5 {
        dict.push_function(Arc::new(Wave {
            freq: 1.3 * k as f64,
        }))
        .unwrap();
    }
    let bytes = dict.to_bytes().unwrap();
    assert_eq!(&bytes[..8], DICTIONARY_MAGIC);
    let back = Dictionary::from_bytes(&bytes, &registry()).unwrap();
    assert_eq!(back.len(), dict.len());
    assert_eq!(back.patch_size(), 8);
    assert_eq!(back.spacing(), dict.spacing());
    assert_eq!(back.support_radius(), dict.support_radius());
    assert_eq!(back.discretize(), dict.discretize());
    assert_eq!(back.to_bytes().unwrap(), bytes);
    // Encoding with the read-back dictionary gives the same terrain bit for bit.
    let s = EncodeSettings {
        sparsity: 3,
        ..Default::default()
    };
    let a = encode(&hf, &dict, &s).unwrap();
    let b = encode(&hf, &back, &s).unwrap();
    assert_eq!(a.to_bytes().unwrap(), b.to_bytes().unwrap());
    let ra = a.rasterize(&RasterSettings::default()).unwrap();
    let rb = b.rasterize(&RasterSettings::default()).unwrap();
    assert_eq!(ra.as_slice(), rb.as_slice());
}

#[test]
fn corrupt_and_hostile_bytes_are_errors() {
    let Some(hf) = relief_testdata::dem_crop("alps_dem", 900, 500, 40, 40) else {
        return;
    };
    let p = extract_patches(&hf, &PatchGeometry::with_patch_size(6)).unwrap();
    let (mut dict, _) = Dictionary::from_patches(&p, Some(&[0, 5, 9, 17])).unwrap();
    dict.push_function(Arc::new(Wave { freq: 2.0 })).unwrap();
    let bytes = dict.to_bytes().unwrap();
    // Every truncation and (the checksum, version 2) every single-byte change is an error.
    relief_testdata::assert_truncations_and_flips_refused(&bytes, 0..bytes.len(), 0x21, |b| {
        Dictionary::from_bytes(b, &registry())
    });
    let mut long = bytes.clone();
    long.push(7);
    assert!(Dictionary::from_bytes(&long, &registry()).is_err());
    // A .sct stream is not a dictionary.
    let mut sct_magic = bytes.clone();
    sct_magic[..8].copy_from_slice(b"RLFSCT\r\n");
    assert!(matches!(
        Dictionary::from_bytes(&sct_magic, &registry()),
        Err(SparseError::Format { offset: 0, .. })
    ));
    let mut v = bytes.clone();
    v[8] = 9;
    reseal(&mut v);
    assert!(Dictionary::from_bytes(&v, &registry()).is_err());
    let mut f = bytes.clone();
    f[10] = 1;
    reseal(&mut f);
    assert!(Dictionary::from_bytes(&f, &registry()).is_err());
    // Version 1 (no checksum) is still read.
    let mut v1 = bytes.clone();
    v1.truncate(v1.len() - 4);
    v1[8..10].copy_from_slice(&1u16.to_le_bytes());
    assert_eq!(
        Dictionary::from_bytes(&v1, &registry()).unwrap().len(),
        Dictionary::from_bytes(&bytes, &registry()).unwrap().len()
    );
    // Absurd atom count (header 12 bytes, then a u16, delta f64, R f64, N u32 at 30); the
    // edited streams are re-sealed, so the reader's own checks refuse them.
    let mut c = bytes.clone();
    c[30..34].copy_from_slice(&u32::MAX.to_le_bytes());
    reseal(&mut c);
    assert!(matches!(
        Dictionary::from_bytes(&c, &registry()),
        Err(SparseError::Format { .. })
    ));
    // A data atom that is not unit-norm (first sample of atom 0 at 35) is refused.
    let mut c = bytes.clone();
    c[35..39].copy_from_slice(&5.0f32.to_le_bytes());
    reseal(&mut c);
    let e = Dictionary::from_bytes(&c, &registry()).unwrap_err();
    assert!(e.to_string().contains("norm"), "{e}");
    // Unknown function kind without the registry.
    assert!(Dictionary::from_bytes(&bytes, &FunctionAtomRegistry::new()).is_err());
    // Random byte edits never panic.
    let mut rng = Pcg64::seed_from_u64(5);
    for _ in 0..500 {
        let mut c = bytes.clone();
        for _ in 0..rng.random_range(1..4) {
            let i = rng.random_range(0..c.len());
            c[i] = rng.random();
        }
        let _ = Dictionary::from_bytes(&c, &registry());
    }
}

/// Rewrites the trailing CRC-32 of an edited stream.
fn reseal(bytes: &mut [u8]) {
    let n = bytes.len() - 4;
    let crc = relief_sparse_core::format::crc32(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
}
