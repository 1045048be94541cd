//! A hand-placed arch between two feet (an arc of capsules); the natural arches of a recipe
//! are in `arches.rs`, hoodoos in `hoodoos.rs`, floating islands in `islands.rs`.

use super::*;

impl SceneBuilder {
    /// One arch between two feet given in scene `(x, y)`: capsules along an arc rising `height`
    /// above the higher foot, warped.
    pub fn arch(
        &mut self,
        a: [f32; 2],
        b: [f32; 2],
        height: f32,
        thickness: f32,
        seed: u32,
    ) -> Result<NodeId> {
        self.check_len("height", height)?;
        self.check_len("thickness", thickness)?;
        if !a.iter().chain(&b).all(|v| v.is_finite()) {
            return Err(Error::param(
                "arch feet",
                format!("{a:?} -> {b:?}"),
                "must be finite",
            ));
        }
        let za = self.ground(a[0], a[1]);
        let zb = self.ground(b[0], b[1]);
        let (pa, pb) = ([a[0], a[1], za - thickness], [b[0], b[1], zb - thickness]);
        let top = za.max(zb) + height;
        let n = 12;
        let pt = |t: f32| {
            let q = add(pa, mul(sub(pb, pa), t));
            let lift = (top - q[2]) * (std::f32::consts::PI * t).sin();
            [q[0], q[1], q[2] + lift]
        };
        let mut parts = Vec::new();
        for k in 0..n {
            let (t0, t1) = (k as f32 / n as f32, (k + 1) as f32 / n as f32);
            let r =
                thickness * (1.0 + 0.6 * (1.0 - (std::f32::consts::PI * (t0 + t1) * 0.5).sin()));
            parts.push(self.tree.capsule(pt(t0), pt(t1), r, 1.0)?);
        }
        let bl = self.tree.blend(&parts)?;
        let w = self
            .tree
            .warp(bl, 0.12 * thickness, 1.0 / thickness, seed)?;
        self.positives.push(w);
        Ok(w)
    }
}
