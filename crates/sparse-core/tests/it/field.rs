//! The field node (a raster of samples interpolated with a kernel, the residual of an
//! amplification step): interpolation at the samples, constants and ramps reproduced, the
//! phase behaviour that makes Lanczos-3 the residual's default, its `.sct` encoding and the
//! errors on bad fields and bad bytes.

use relief_heightfield::{Kernel, MAX_CELLS};
use relief_sparse_core::{Field, Node, RasterSettings, Sct, SparseError};

fn field(w: usize, h: usize, f: impl Fn(usize, usize) -> f32, kernel: Kernel) -> Field {
    let v = (0..w * h).map(|k| f(k % w, k / w)).collect();
    Field::new(w, h, v, [1.5, 1.5], 4.0, kernel).unwrap()
}

#[test]
fn interpolates_the_samples_and_reproduces_constants_and_ramps() {
    let wavy = |x: usize, y: usize| ((x * 7 + y * 13) % 11) as f32 - 5.0;
    for kernel in [Kernel::Keys, Kernel::Lanczos3] {
        let f = field(12, 9, wavy, kernel);
        for (x, y) in [(0, 0), (5, 3), (11, 8), (7, 1)] {
            let v = f.eval(1.5 + 4.0 * x as f64, 1.5 + 4.0 * y as f64);
            assert!(
                (v - wavy(x, y) as f64).abs() < 1e-9,
                "{kernel:?} at ({x}, {y}): {v}"
            );
        }
        let c = field(10, 10, |_, _| 42.0, kernel);
        for p in [(0.0, 0.0), (13.2, 17.9), (39.9, 2.5)] {
            assert!(
                (c.eval(p.0, p.1) - 42.0).abs() < 1e-9,
                "{kernel:?} constant at {p:?}"
            );
        }
    }
    // Keys reproduces linear ramps exactly away from the clamped edges.
    let ramp = field(12, 12, |x, y| 3.0 * x as f32 - 2.0 * y as f32, Kernel::Keys);
    for p in [(13.3, 17.0), (25.0, 21.7), (30.1, 30.9)] {
        let want = 3.0 * (p.0 - 1.5) / 4.0 - 2.0 * (p.1 - 1.5) / 4.0;
        assert!((ramp.eval(p.0, p.1) - want).abs() < 1e-9, "ramp at {p:?}");
    }
}

/// Energy of the high-pass (value minus its Gaussian blur of 2 pixels, as the phase-swing
/// measure of the amplification) by row phase modulo 4 of a x4 raster of `f`, each over
/// their mean.
fn phase_energy(f: &Field, w: usize) -> [f64; 4] {
    let t = Sct::new(Node::Field(f.clone()), 4 * w, 4 * w, (1.0, 1.0)).unwrap();
    let r = t.rasterize(&RasterSettings::default()).unwrap();
    let b = r.gaussian_blur(2.0).unwrap();
    let n = 4 * w;
    let mut e = [0.0; 4];
    for y in 16..n - 16 {
        for x in 16..n - 16 {
            let d = r.get(x, y) as f64 - b.get(x, y) as f64;
            e[y % 4] += d * d;
        }
    }
    let mean = e.iter().sum::<f64>() / 4.0;
    e.map(|v| v / mean)
}

#[test]
fn lanczos3_keeps_near_nyquist_energy_even_across_phases() {
    // Samples of waves at 0.3-0.45 cycles per sample (near the grid's Nyquist frequency, as
    // a box-reduced rough terrain carries): the interpolation's high-pass energy per row phase.
    let w = 64;
    let swing = |k, fr: f64| {
        let wave = |_: usize, y: usize| (std::f64::consts::TAU * fr * y as f64).sin() as f32;
        let e = phase_energy(&field(w, w, wave, k), w);
        e.iter().cloned().fold(0.0, f64::max) / e.iter().cloned().fold(f64::MAX, f64::min)
    };
    // At 0.3 cycles per sample: Keys 2.39x, Lanczos-3 1.11x.
    let (keys, lanczos) = (swing(Kernel::Keys, 0.3), swing(Kernel::Lanczos3, 0.3));
    assert!(lanczos < 1.2, "Lanczos-3 swing {lanczos}");
    assert!(keys > 2.0, "Keys swing {keys}");
    // Nearer Nyquist both swing more, Lanczos-3 still half as much (3.65x against 1.84x).
    let (keys, lanczos) = (swing(Kernel::Keys, 0.37), swing(Kernel::Lanczos3, 0.37));
    assert!(lanczos < 0.6 * keys, "Keys {keys}, Lanczos-3 {lanczos}");
}

#[test]
fn bad_fields_are_errors_naming_the_problem() {
    let k = Kernel::Lanczos3;
    let err = |r: Result<Field, SparseError>| r.unwrap_err().to_string();
    assert!(err(Field::new(3, 3, vec![0.0; 8], [0.0; 2], 1.0, k)).contains("field size"));
    assert!(err(Field::new(0, 3, vec![], [0.0; 2], 1.0, k)).contains("field size"));
    let huge = Field::new(MAX_CELLS, 2, vec![0.0; 4], [0.0; 2], 1.0, k);
    assert!(err(huge).contains("field size"));
    let mut v = vec![1.0; 9];
    v[4] = f32::NAN;
    assert!(err(Field::new(3, 3, v, [0.0; 2], 1.0, k)).contains("field sample"));
    for (o, s) in [
        ([0.0, f64::NAN], 1.0),
        ([0.0; 2], 0.0),
        ([0.0; 2], f64::INFINITY),
    ] {
        assert!(err(Field::new(3, 3, vec![0.0; 9], o, s, k)).contains("field placement"));
    }
}

#[test]
fn field_round_trips_and_bad_bytes_are_errors() {
    let f = field(5, 4, |x, y| (x * y) as f32 + 0.25, Kernel::Keys);
    let t = Sct::new(
        Node::Add(vec![Node::Constant(10.0), Node::Field(f)]),
        20,
        16,
        (2.0, 2.0),
    )
    .unwrap();
    let bytes = t.to_bytes().unwrap();
    let back = Sct::from_bytes(&bytes, &Default::default()).unwrap();
    assert_eq!(back.to_bytes().unwrap(), bytes);
    let (a, b) = (
        t.rasterize(&RasterSettings::default()).unwrap(),
        back.rasterize(&RasterSettings::default()).unwrap(),
    );
    assert_eq!(a.as_slice(), b.as_slice());
    // Every truncation is an error, never a panic.
    for n in (0..bytes.len()).step_by(7) {
        assert!(Sct::from_bytes(&bytes[..n], &Default::default()).is_err());
    }
}

/// Bytes of a model whose root is a field with the given header (the checksum recomputed, so
/// only the field's own checks can refuse it).
fn field_stream(kernel: u8, w: u32, h: u32, samples: usize) -> Vec<u8> {
    let t = Sct::new(Node::Constant(0.0), 8, 8, (1.0, 1.0)).unwrap();
    let mut b = t.to_bytes().unwrap();
    b.truncate(b.len() - 4);
    // The constant node is the last 9 bytes of the body (tag 1 and an f64).
    b.truncate(b.len() - 9);
    b.push(8);
    b.push(kernel);
    b.extend_from_slice(&w.to_le_bytes());
    b.extend_from_slice(&h.to_le_bytes());
    for v in [1.5f64, 1.5, 4.0] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for _ in 0..samples {
        b.extend_from_slice(&1.0f32.to_le_bytes());
    }
    let crc = relief_sparse_core::format::crc32(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

#[test]
fn hostile_field_headers_are_refused_before_allocating() {
    let read = |b: Vec<u8>| Sct::from_bytes(&b, &Default::default()).map(|_| ());
    assert!(read(field_stream(1, 2, 2, 4)).is_ok());
    let e = read(field_stream(7, 2, 2, 4)).unwrap_err().to_string();
    assert!(e.contains("unknown field kernel 7"), "{e}");
    // A declared size far beyond the bytes present: refused before any allocation.
    let e = read(field_stream(0, u32::MAX, u32::MAX, 4))
        .unwrap_err()
        .to_string();
    assert!(e.contains("field sample"), "{e}");
    let e = read(field_stream(0, 0, 5, 0)).unwrap_err().to_string();
    assert!(e.contains("field size"), "{e}");
}
