//! Triangle mesh writers: Wavefront OBJ, binary little-endian PLY and glTF 2.0 binary (GLB),
//! all written atomically, with optional vertex normals and sRGB vertex colours.

use std::fmt::Write as _;
use std::path::Path;

use crate::{IoError, Result, atomic};

/// A mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (text, 1-based indices, `vn` when normals are given, colours as the
    /// widely read `v x y z r g b` extension with sRGB values in `[0, 1]`).
    Obj,
    /// Binary little-endian PLY (`float x y z [nx ny nz] [uchar red green blue alpha]`,
    /// `list uchar uint vertex_indices`).
    Ply,
    /// glTF 2.0 binary: one JSON chunk and one BIN chunk, 4-byte aligned; colours as `COLOR_0`
    /// (linear, normalised unsigned short, as the specification wants) with a rough,
    /// non-metallic white material that they multiply.
    Glb,
}

impl MeshFormat {
    /// From a file extension (`obj`, `ply`, `glb`, case-insensitive).
    pub fn from_extension(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply),
            "glb" => Some(MeshFormat::Glb),
            _ => None,
        }
    }
}

/// Writes a triangle mesh to `path`; the format comes from the extension (`.obj`, `.ply`,
/// `.glb`). `normals` and `colours` (sRGB, alpha last), when given, have one entry per
/// position.
pub fn write_mesh(
    path: &Path,
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    normals: Option<&[[f32; 3]]>,
    colours: Option<&[[u8; 4]]>,
) -> Result<()> {
    let f = MeshFormat::from_extension(path).ok_or_else(|| {
        IoError::UnknownFormat(format!(
            "{}: mesh extension must be .obj, .ply or .glb",
            path.display()
        ))
    })?;
    write_mesh_as(path, f, positions, triangles, normals, colours)
}

/// Writes a triangle mesh to `path` in format `f` (atomically).
pub fn write_mesh_as(
    path: &Path,
    f: MeshFormat,
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    normals: Option<&[[f32; 3]]>,
    colours: Option<&[[u8; 4]]>,
) -> Result<()> {
    let bytes =
        encode_mesh(f, positions, triangles, normals, colours).map_err(|e| e.in_file(path))?;
    atomic::write_atomic(path, &bytes)
}

fn validate(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    normals: Option<&[[f32; 3]]>,
    colours: Option<&[[u8; 4]]>,
) -> Result<()> {
    if let Some(c) = colours
        && c.len() != positions.len()
    {
        return Err(IoError::param(
            "colours",
            c.len(),
            format!("need one per position ({})", positions.len()),
        ));
    }
    if positions.is_empty() || triangles.is_empty() {
        return Err(IoError::param(
            "mesh",
            format!(
                "{} positions, {} triangles",
                positions.len(),
                triangles.len()
            ),
            "a mesh needs at least one position and one triangle",
        ));
    }
    if positions.len() > u32::MAX as usize {
        return Err(IoError::param(
            "positions",
            positions.len(),
            "more than 2^32 - 1 vertices",
        ));
    }
    if let Some(i) = positions
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        return Err(IoError::param(
            "positions",
            format!("{:?} at {i}", positions[i]),
            "must be finite",
        ));
    }
    if let Some(n) = normals {
        if n.len() != positions.len() {
            return Err(IoError::param(
                "normals",
                n.len(),
                format!("need one per position ({})", positions.len()),
            ));
        }
        if let Some(i) = n.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(IoError::param(
                "normals",
                format!("{:?} at {i}", n[i]),
                "must be finite",
            ));
        }
    }
    let nv = positions.len() as u64;
    if let Some((i, t)) = triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&v| v as u64 >= nv))
    {
        return Err(IoError::param(
            "triangles",
            format!("{t:?} at {i}"),
            format!("index out of range for {nv} positions"),
        ));
    }
    Ok(())
}

/// Encodes a mesh as the bytes of format `f`.
pub fn encode_mesh(
    f: MeshFormat,
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    normals: Option<&[[f32; 3]]>,
    colours: Option<&[[u8; 4]]>,
) -> Result<Vec<u8>> {
    validate(positions, triangles, normals, colours)?;
    let m = Parts {
        p: positions,
        t: triangles,
        n: normals,
        colours,
    };
    Ok(match f {
        MeshFormat::Obj => obj(&m),
        MeshFormat::Ply => ply(&m),
        MeshFormat::Glb => glb(&m)?,
    })
}

/// A validated mesh: positions, triangles, and the optional per-position normals and colours.
struct Parts<'a> {
    p: &'a [[f32; 3]],
    t: &'a [[u32; 3]],
    n: Option<&'a [[f32; 3]]>,
    colours: Option<&'a [[u8; 4]]>,
}

fn obj(m: &Parts) -> Vec<u8> {
    let (p, t, n, colours) = (m.p, m.t, m.n, m.colours);
    let mut s = String::with_capacity(p.len() * 40 + t.len() * 30);
    s.push_str("# written by relief-io\n");
    for (i, v) in p.iter().enumerate() {
        let _ = write!(s, "v {} {} {}", v[0], v[1], v[2]);
        if let Some(c) = colours {
            let [r, g, b, _] = c[i].map(|x| x as f32 / 255.0);
            let _ = write!(s, " {r:.4} {g:.4} {b:.4}");
        }
        s.push('\n');
    }
    if let Some(n) = n {
        for v in n {
            let _ = writeln!(s, "vn {} {} {}", v[0], v[1], v[2]);
        }
    }
    for tri in t {
        let [a, b, c] = tri.map(|i| i as u64 + 1);
        if n.is_some() {
            let _ = writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}");
        } else {
            let _ = writeln!(s, "f {a} {b} {c}");
        }
    }
    s.into_bytes()
}

fn ply(m: &Parts) -> Vec<u8> {
    let (p, t, n, colours) = (m.p, m.t, m.n, m.colours);
    let mut h = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by relief-io\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        p.len()
    );
    if n.is_some() {
        h.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    if colours.is_some() {
        h.push_str(
            "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n",
        );
    }
    let _ = write!(
        h,
        "element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        t.len()
    );
    let mut out = h.into_bytes();
    out.reserve(p.len() * 24 + t.len() * 13);
    for (i, v) in p.iter().enumerate() {
        for c in v {
            out.extend_from_slice(&c.to_le_bytes());
        }
        if let Some(n) = n {
            for c in &n[i] {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        if let Some(c) = colours {
            out.extend_from_slice(&c[i]);
        }
    }
    for tri in t {
        out.push(3);
        for i in tri {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    out
}

/// relief's Z-up frame (x east, y north, z up) to glTF's Y-up frame (x right, y up, z toward
/// the viewer): a rotation of -90 degrees about x, `(x, y, z) -> (x, z, -y)`, so triangle winding
/// and handedness are kept and engines and Blender show the terrain lying flat.
pub fn z_up_to_y_up(v: &[f32; 3]) -> [f32; 3] {
    [v[0], v[2], -v[1]]
}

/// An 8-bit sRGB value to linear light as a normalised unsigned short (glTF's `COLOR_0` is
/// linear).
fn srgb_to_linear_u16(v: u8) -> u16 {
    let c = v as f64 / 255.0;
    let l = if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    };
    (l * 65535.0).round() as u16
}

fn glb(m: &Parts) -> Result<Vec<u8>> {
    let (p, t, n, colours) = (m.p, m.t, m.n, m.colours);
    let p: Vec<[f32; 3]> = p.iter().map(z_up_to_y_up).collect();
    let n: Option<Vec<[f32; 3]>> = n.map(|n| n.iter().map(z_up_to_y_up).collect());
    let (p, n) = (p.as_slice(), n.as_deref());
    // BIN layout: positions, [normals], indices; every view starts 4-byte aligned (all
    // components are 4 bytes wide, so the views are contiguous).
    let mut bin = Vec::with_capacity(p.len() * 24 + t.len() * 12);
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for v in p {
        for k in 0..3 {
            min[k] = min[k].min(v[k]);
            max[k] = max[k].max(v[k]);
            bin.extend_from_slice(&v[k].to_le_bytes());
        }
    }
    let pos_len = bin.len();
    if let Some(n) = n {
        for v in n {
            for c in v {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    let nrm_len = bin.len() - pos_len;
    if let Some(c) = colours {
        let lut: Vec<u16> = (0..=255u8).map(srgb_to_linear_u16).collect();
        for v in c {
            for k in 0..3 {
                bin.extend_from_slice(&lut[v[k] as usize].to_le_bytes());
            }
            bin.extend_from_slice(&((v[3] as u16) * 257).to_le_bytes());
        }
    }
    let col_len = bin.len() - pos_len - nrm_len;
    for tri in t {
        for i in tri {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let idx_len = bin.len() - pos_len - nrm_len - col_len;
    let mut views = vec![
        serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": pos_len, "target": 34962}),
    ];
    let mut accessors = vec![serde_json::json!({
        "bufferView": 0, "componentType": 5126, "count": p.len(), "type": "VEC3",
        "min": min, "max": max
    })];
    let mut attributes = serde_json::json!({"POSITION": 0});
    if n.is_some() {
        views.push(serde_json::json!({"buffer": 0, "byteOffset": pos_len, "byteLength": nrm_len, "target": 34962}));
        accessors.push(serde_json::json!({"bufferView": 1, "componentType": 5126, "count": p.len(), "type": "VEC3"}));
        attributes["NORMAL"] = serde_json::json!(1);
    }
    let mut material = None;
    if colours.is_some() {
        let cv = views.len();
        views.push(serde_json::json!({"buffer": 0, "byteOffset": pos_len + nrm_len, "byteLength": col_len, "target": 34962}));
        accessors.push(serde_json::json!({"bufferView": cv, "componentType": 5123, "normalized": true, "count": p.len(), "type": "VEC4"}));
        attributes["COLOR_0"] = serde_json::json!(accessors.len() - 1);
        material = Some(serde_json::json!({
            "name": "relief-rock",
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9}
        }));
    }
    let iv = views.len();
    views.push(serde_json::json!({"buffer": 0, "byteOffset": pos_len + nrm_len + col_len, "byteLength": idx_len, "target": 34963}));
    accessors.push(serde_json::json!({"bufferView": iv, "componentType": 5125, "count": t.len() * 3, "type": "SCALAR"}));
    let ia = accessors.len() - 1;
    let mut primitive = serde_json::json!({"attributes": attributes, "indices": ia, "mode": 4});
    let mut json = serde_json::json!({
        "asset": {"version": "2.0", "generator": "relief-io"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": views,
        "accessors": accessors,
    });
    if let Some(m) = material {
        primitive["material"] = serde_json::json!(0);
        json["materials"] = serde_json::json!([m]);
    }
    json["meshes"] = serde_json::json!([{"primitives": [primitive]}]);
    let mut js = serde_json::to_vec(&json).unwrap_or_default();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + js.len() + 8 + bin.len();
    if total > u32::MAX as usize {
        return Err(IoError::param(
            "mesh",
            total,
            "a GLB file is limited to 4 GiB",
        ));
    }
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(js.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(&js);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}
