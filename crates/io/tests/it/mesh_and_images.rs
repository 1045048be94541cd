//! Mesh writers (OBJ, binary PLY, GLB) parsed back, and the preview / helper PNGs.

use relief_heightfield::Heightfield;
use relief_io::{MeshFormat, write_gray_png, write_mesh, write_preview_png, write_rgb_png};

/// A closed tetrahedron with outward normals.
type Mesh = (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<[f32; 3]>);

fn tetra() -> Mesh {
    let p: Vec<[f32; 3]> = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let n = p
        .iter()
        .map(|v| {
            let c = [v[0] - 0.25, v[1] - 0.25, v[2] - 0.25];
            let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            [c[0] / l, c[1] / l, c[2] / l]
        })
        .collect();
    (p, t, n)
}

fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

/// The bytes of [`tetra`] written with normals as `name` (format from the extension), and its
/// triangles.
fn written_tetra(name: &str) -> (Vec<u8>, Vec<[u32; 3]>) {
    let (p, t, n) = tetra();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    write_mesh(&path, &p, &t, Some(&n), None).unwrap();
    (std::fs::read(&path).unwrap(), t)
}

#[test]
fn obj_parses_back() {
    let (bytes, t) = written_tetra("m.obj");
    let text = String::from_utf8(bytes).unwrap();
    let verts: Vec<Vec<f32>> = text
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| l[2..].split(' ').map(|s| s.parse().unwrap()).collect())
        .collect();
    assert_eq!(verts.len(), 4);
    assert_eq!(verts[3], vec![0.0, 0.0, 1.0]);
    assert_eq!(text.lines().filter(|l| l.starts_with("vn ")).count(), 4);
    let faces: Vec<Vec<u32>> = text
        .lines()
        .filter(|l| l.starts_with("f "))
        .map(|l| {
            l[2..]
                .split(' ')
                .map(|s| s.split("//").next().unwrap().parse().unwrap())
                .collect()
        })
        .collect();
    assert_eq!(faces.len(), 4);
    for (f, tri) in faces.iter().zip(&t) {
        assert_eq!(f, &tri.iter().map(|i| i + 1).collect::<Vec<_>>());
    }
    // Closed: every edge is used exactly twice, once in each direction.
    let mut edges = std::collections::HashMap::new();
    for f in &faces {
        for k in 0..3 {
            *edges.entry((f[k], f[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    assert!(edges.keys().all(|&(a, b)| edges.get(&(b, a)) == Some(&1)));
}

#[test]
fn ply_parses_back() {
    let (b, t) = written_tetra("m.ply");
    let end = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let header = std::str::from_utf8(&b[..end]).unwrap();
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    assert!(header.contains("element vertex 4\n") && header.contains("element face 4\n"));
    assert!(header.contains("property float nz\n"));
    assert_eq!(b.len(), end + 4 * 24 + 4 * 13, "vertex + face payload size");
    let body = &b[end..];
    let z3 = f32::from_le_bytes(body[3 * 24 + 8..3 * 24 + 12].try_into().unwrap());
    assert_eq!(z3, 1.0);
    let f = &body[4 * 24..];
    for (k, tri) in t.iter().enumerate() {
        let o = k * 13;
        assert_eq!(f[o], 3);
        assert_eq!([u32_at(f, o + 1), u32_at(f, o + 5), u32_at(f, o + 9)], *tri);
    }
}

#[test]
fn glb_chunks_and_accessors_are_valid() {
    let (p, t, n) = tetra();
    let dir = tempfile::tempdir().unwrap();
    let colours = [
        [255, 0, 0, 255],
        [0, 128, 0, 255],
        [0, 0, 255, 128],
        [188, 188, 188, 255],
    ];
    for (normals, colours) in [
        (None, None),
        (Some(n.as_slice()), None),
        (Some(n.as_slice()), Some(colours.as_slice())),
        (None, Some(colours.as_slice())),
    ] {
        let path = dir.path().join("m.glb");
        write_mesh(&path, &p, &t, normals, colours).unwrap();
        let b = std::fs::read(&path).unwrap();
        assert_eq!(&b[0..4], b"glTF");
        assert_eq!(u32_at(&b, 4), 2);
        assert_eq!(u32_at(&b, 8) as usize, b.len());
        let jl = u32_at(&b, 12) as usize;
        assert_eq!(u32_at(&b, 16), 0x4E4F_534A);
        assert_eq!(jl % 4, 0);
        let json: serde_json::Value = serde_json::from_slice(&b[20..20 + jl]).unwrap();
        let bo = 20 + jl;
        let bl = u32_at(&b, bo) as usize;
        assert_eq!(u32_at(&b, bo + 4), 0x004E_4942);
        assert_eq!(bl % 4, 0);
        assert_eq!(bo + 8 + bl, b.len());
        let bin = &b[bo + 8..];
        assert_eq!(json["asset"]["version"], "2.0");
        assert_eq!(
            json["buffers"][0]["byteLength"].as_u64().unwrap() as usize,
            bl
        );
        let prim = &json["meshes"][0]["primitives"][0];
        let acc = |i: &serde_json::Value| &json["accessors"][i.as_u64().unwrap() as usize];
        let pos = acc(&prim["attributes"]["POSITION"]);
        assert_eq!(pos["count"], 4);
        assert_eq!(pos["type"], "VEC3");
        // glTF is Y-up: relief's (x, y, z) is stored as (x, z, -y).
        assert_eq!(pos["max"], serde_json::json!([1.0, 1.0, 0.0]));
        assert_eq!(pos["min"], serde_json::json!([0.0, 0.0, -1.0]));
        let pv = &json["bufferViews"][pos["bufferView"].as_u64().unwrap() as usize];
        let po = pv["byteOffset"].as_u64().unwrap() as usize;
        let f32_at = |o: usize| f32::from_le_bytes(bin[o..o + 4].try_into().unwrap());
        for (k, v) in p.iter().enumerate() {
            let got = [
                f32_at(po + 12 * k),
                f32_at(po + 12 * k + 4),
                f32_at(po + 12 * k + 8),
            ];
            assert_eq!(got, [v[0], v[2], -v[1]], "vertex {k}");
        }
        assert_eq!(
            prim["attributes"].get("NORMAL").is_some(),
            normals.is_some()
        );
        // Colours: linear normalised u16 (sRGB 188 is linear 0.5029), under a white material.
        assert_eq!(
            prim["attributes"].get("COLOR_0").is_some(),
            colours.is_some()
        );
        assert_eq!(prim.get("material").is_some(), colours.is_some());
        if colours.is_some() {
            let c = acc(&prim["attributes"]["COLOR_0"]);
            assert_eq!(
                (c["componentType"].as_u64(), c["type"].as_str()),
                (Some(5123), Some("VEC4"))
            );
            assert_eq!(c["normalized"], true);
            let cv = &json["bufferViews"][c["bufferView"].as_u64().unwrap() as usize];
            let co = cv["byteOffset"].as_u64().unwrap() as usize;
            let u16_at = |o: usize| u16::from_le_bytes([bin[o], bin[o + 1]]) as f64 / 65535.0;
            assert_eq!(
                [u16_at(co), u16_at(co + 2), u16_at(co + 4), u16_at(co + 6)],
                [1.0, 0.0, 0.0, 1.0]
            );
            assert!(
                (u16_at(co + 8 + 2) - 0.2158).abs() < 1e-3,
                "sRGB 128 -> linear"
            );
            assert!(
                (u16_at(co + 16 + 6) - 128.0 / 255.0).abs() < 1e-4,
                "alpha stays linear"
            );
            assert!((u16_at(co + 24) - 0.5029).abs() < 1e-3);
            let m = &json["materials"][0]["pbrMetallicRoughness"];
            assert_eq!(m["metallicFactor"], 0.0);
        }
        let idx = acc(&prim["indices"]);
        assert_eq!(idx["count"], 12);
        assert_eq!(idx["componentType"], 5125);
        // Every buffer view lies inside the BIN chunk and the indices read back.
        for v in json["bufferViews"].as_array().unwrap() {
            let (o, l) = (
                v["byteOffset"].as_u64().unwrap() as usize,
                v["byteLength"].as_u64().unwrap() as usize,
            );
            assert!(o % 4 == 0 && o + l <= bl);
        }
        let iv = &json["bufferViews"][idx["bufferView"].as_u64().unwrap() as usize];
        let io = iv["byteOffset"].as_u64().unwrap() as usize;
        let got: Vec<u32> = (0..12).map(|k| u32_at(bin, io + 4 * k)).collect();
        assert_eq!(got, t.concat());
    }
}

#[test]
fn mesh_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (p, _, _) = tetra();
    assert!(write_mesh(&dir.path().join("m.obj"), &p, &[[0, 1, 9]], None, None).is_err());
    assert!(write_mesh(&dir.path().join("m.stl"), &p, &[[0, 1, 2]], None, None).is_err());
    assert!(
        write_mesh(
            &dir.path().join("m.ply"),
            &p,
            &[[0, 1, 2]],
            Some(&[[0.0; 3]]),
            None
        )
        .is_err()
    );
    let e = write_mesh(
        &dir.path().join("m.glb"),
        &p,
        &[[0, 1, 2]],
        None,
        Some(&[[0; 4]; 3]),
    )
    .unwrap_err();
    assert!(e.to_string().contains("colours"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    assert_eq!(
        MeshFormat::from_extension(std::path::Path::new("a.GLB")),
        Some(MeshFormat::Glb)
    );
}

fn png_header(path: &std::path::Path) -> (u32, u32, u8, u8) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n");
    let be = |o: usize| u32::from_be_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    (be(16), be(20), b[24], b[25])
}

#[test]
fn preview_and_helper_pngs() {
    let dir = tempfile::tempdir().unwrap();
    let mut hf = Heightfield::from_fn(40, 30, 10.0, 10.0, |x, y| {
        ((x as f32 * 0.3).sin() + y as f32 * 0.1) * 50.0
    });
    hf.set(3, 4, f32::NAN);
    let p = dir.path().join("prev.png");
    write_preview_png(&p, &hf).unwrap();
    assert_eq!(png_header(&p), (40, 30, 8, 2));
    let rgb = relief_io::preview_rgb(&hf).unwrap();
    assert_eq!(
        &rgb[(4 * 40 + 3) * 3..(4 * 40 + 3) * 3 + 3],
        &[220, 30, 30],
        "voids are red"
    );
    // Shading varies with the terrain.
    assert!(
        rgb.chunks(3)
            .map(|c| c[0])
            .collect::<std::collections::HashSet<_>>()
            .len()
            > 20
    );
    let g = dir.path().join("g.png");
    write_gray_png(&g, 4, 2, &[0, 50, 100, 150, 200, 250, 255, 1]).unwrap();
    assert_eq!(png_header(&g), (4, 2, 8, 0));
    let c = dir.path().join("c.png");
    write_rgb_png(&c, 2, 1, &[1, 2, 3, 4, 5, 6]).unwrap();
    assert_eq!(png_header(&c), (2, 1, 8, 2));
    assert!(write_rgb_png(&dir.path().join("bad.png"), 2, 2, &[0; 5]).is_err());
    assert!(!dir.path().join("bad.png").exists());
}

/// An RGBA map written row by row has the bytes of the one written whole, decodes to the
/// pixels given, and leaves nothing when it is not finished.
#[test]
fn rgba_png_rows_equal_the_whole_image() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37usize, 29usize);
    let rgba: Vec<u8> = (0..w * h * 4).map(|i| ((i * 7919) % 251) as u8).collect();
    let whole = dir.path().join("whole.png");
    relief_io::write_rgba_png(&whole, w, h, &rgba).unwrap();
    let rows = dir.path().join("rows.png");
    let mut wr = relief_io::RgbaPngWriter::create(&rows, w, h).unwrap();
    for band in rgba.chunks(w * 4 * 10) {
        wr.write_rows(band).unwrap();
    }
    assert!(wr.write_rows(&[0; 4]).is_err(), "not a whole row");
    wr.finish().unwrap();
    let (a, b) = (
        std::fs::read(&whole).unwrap(),
        std::fs::read(&rows).unwrap(),
    );
    assert_eq!(a, b);
    let mut dec = png::Decoder::new(std::io::Cursor::new(a))
        .read_info()
        .unwrap();
    let mut px = vec![0; dec.output_buffer_size().unwrap()];
    dec.next_frame(&mut px).unwrap();
    assert_eq!(px, rgba);
    let part = dir.path().join("part.png");
    let mut wr = relief_io::RgbaPngWriter::create(&part, w, h).unwrap();
    wr.write_rows(&rgba[..w * 4]).unwrap();
    assert!(wr.finish().is_err());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        2,
        "no temporary is left"
    );
}

/// Issue 14: sea colours below 0 m (blue by depth) when there is land too, the light and the
/// exaggeration act, and a bad style names its field.
#[test]
fn preview_style_draws_the_sea_and_moves_the_light() {
    use relief_io::{PreviewStyle, preview_rgb_with};
    // A coast: sea on the left (down to -100 m), land rising to the right (up to 300 m).
    let hf = Heightfield::from_fn(40, 20, 10.0, 10.0, |x, y| {
        (x as f32 - 10.0) * 10.0 + (y as f32 * 0.7).sin() * 5.0
    });
    let px = |rgb: &[u8], x: usize, y: usize| -> [u8; 3] {
        let i = (y * 40 + x) * 3;
        [rgb[i], rgb[i + 1], rgb[i + 2]]
    };
    // The preview in the default style changed by `set`.
    let styled = |set: fn(&mut PreviewStyle)| {
        let mut style = PreviewStyle::default();
        set(&mut style);
        preview_rgb_with(&hf, &style)
    };
    let sea = styled(|_| {}).unwrap();
    let [r, g, b] = px(&sea, 2, 10);
    assert!(b > r + 40 && b > g, "sea pixel {r},{g},{b} is not blue");
    let [r, g, b] = px(&sea, 30, 10);
    assert!(!(b > r + 40 && b > g), "land pixel {r},{g},{b} is blue");
    let no_sea = styled(|s| s.sea = false).unwrap();
    let [r, g, b] = px(&no_sea, 2, 10);
    assert!(!(b > r + 40 && b > g), "--no-sea pixel {r},{g},{b} is blue");
    // Light from the east instead of the north-west: the east-rising slope darkens.
    let east = styled(|s| s.azimuth_deg = 90.0).unwrap();
    let lum = |p: [u8; 3]| p.iter().map(|&c| c as u32).sum::<u32>();
    assert!(lum(px(&east, 30, 10)) < lum(px(&sea, 30, 10)));
    type Change = fn(&mut PreviewStyle);
    let bad: [(Change, &str); 4] = [
        (|s| s.altitude_deg = 0.0, "altitude"),
        (|s| s.altitude_deg = 95.0, "altitude"),
        (|s| s.exaggeration = -1.0, "exaggeration"),
        (|s| s.azimuth_deg = f32::NAN, "azimuth"),
    ];
    for (set, field) in bad {
        let e = styled(set).unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
}

#[test]
fn obj_and_ply_carry_vertex_colours() {
    let (p, t, n) = tetra();
    let colours = [
        [255, 0, 0, 255],
        [0, 255, 0, 255],
        [0, 0, 255, 255],
        [51, 102, 153, 255],
    ];
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("m.obj");
    write_mesh(&obj, &p, &t, Some(&n), Some(&colours)).unwrap();
    let text = std::fs::read_to_string(&obj).unwrap();
    let last: Vec<f32> = text.lines().filter(|l| l.starts_with("v ")).nth(3).unwrap()[2..]
        .split(' ')
        .map(|s| s.parse().unwrap())
        .collect();
    assert_eq!(last, vec![0.0, 0.0, 1.0, 0.2, 0.4, 0.6]);
    let ply = dir.path().join("m.ply");
    write_mesh(&ply, &p, &t, Some(&n), Some(&colours)).unwrap();
    let b = std::fs::read(&ply).unwrap();
    let end = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let header = std::str::from_utf8(&b[..end]).unwrap();
    assert!(header.contains(
        "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
    ));
    // Vertex records: 6 floats then 4 bytes.
    let rec = 6 * 4 + 4;
    assert_eq!(&b[end + 3 * rec + 24..end + 4 * rec], &[51, 102, 153, 255]);
    assert_eq!(b.len(), end + 4 * rec + 4 * 13);
}
