//! The channel network drawn over a hillshade preview (`relief flow`'s `channels.png` and the
//! pipeline's `flow` stage): every channel cell's D8 step to its receiver is a blue segment,
//! wider and darker with its Strahler order, anti-aliased into the RGB preview of
//! `relief_io::preview_rgb` (of a box-reduced grid for images of bounded size).

use anyhow::{Context, Result, bail};
use relief_heightfield::Heightfield;

/// Light blue of first-order channels.
const LOW: [f32; 3] = [120.0, 180.0, 255.0];
/// Deep blue of the highest order.
const HIGH: [f32; 3] = [0.0, 45.0, 190.0];

/// Width in pixels of a channel of Strahler order `order` (1 px at order 1, 0.75 px more per
/// order).
pub fn line_width(order: u8) -> f32 {
    1.0 + 0.75 * f32::from(order.saturating_sub(1))
}

/// The cell offset `(dx, dy)` of an ESRI direction code (1 east, 2 south-east, ..., 128
/// north-east; rows grow southwards).
fn esri_step(code: u8) -> Option<(i64, i64)> {
    Some(match code {
        1 => (1, 0),
        2 => (1, 1),
        4 => (0, 1),
        8 => (-1, 1),
        16 => (-1, 0),
        32 => (-1, -1),
        64 => (0, -1),
        128 => (1, -1),
        _ => return None,
    })
}

/// RGB bytes (`width x height` triples) of `dem`'s preview with the channels of `strahler`
/// (order > 0) drawn along `direction` (ESRI codes), both on `dem`'s grid.
pub fn channel_map(
    dem: &Heightfield,
    direction: &Heightfield,
    strahler: &Heightfield,
) -> Result<Vec<u8>> {
    Ok(channel_map_within(dem, direction, strahler, usize::MAX)?.2)
}

/// [`channel_map`] of at most `max_side` pixels a side: a larger grid's preview is drawn from
/// its box-averaged reduction by the smallest integer factor that fits, the channels at
/// their positions scaled by it (line widths unchanged). Returns the image's width, height
/// and RGB bytes.
pub fn channel_map_within(
    dem: &Heightfield,
    direction: &Heightfield,
    strahler: &Heightfield,
    max_side: usize,
) -> Result<(usize, usize, Vec<u8>)> {
    let (gw, gh) = (dem.width(), dem.height());
    for g in [direction, strahler] {
        if (g.width(), g.height()) != (gw, gh) {
            bail!("the channel rasters are not on the DEM's grid");
        }
    }
    let k = gw.max(gh).div_ceil(max_side.max(1)).max(1);
    let small;
    let base = if k > 1 {
        small = dem.downsample_box(k)?;
        &small
    } else {
        dem
    };
    let (w, h) = (base.width(), base.height());
    let scale = 1.0 / k as f32;
    let mut rgb = relief_io::preview_rgb(base).context("cannot draw the hillshade preview")?;
    // Per pixel: the largest coverage of any segment, and the highest order covering it.
    let mut cover = vec![0f32; w * h];
    let mut top = vec![0u8; w * h];
    let (dir, ord) = (direction.as_slice(), strahler.as_slice());
    let max_order = ord
        .iter()
        .filter(|o| o.is_finite())
        .fold(0f32, |a, &b| a.max(b))
        .clamp(0.0, 255.0) as u8;
    for i in 0..gw * gh {
        let (o, d) = (ord[i], dir[i]);
        if !(o >= 1.0 && d.is_finite()) {
            continue;
        }
        let Some((dx, dy)) = esri_step(d as u8) else {
            continue;
        };
        let order = o.min(255.0) as u8;
        let (cx, cy) = ((i % gw) as f32 + 0.5, (i / gw) as f32 + 0.5);
        let (x0, y0) = (cx * scale, cy * scale);
        let (x1, y1) = ((cx + dx as f32) * scale, (cy + dy as f32) * scale);
        let r = 0.5 * line_width(order);
        let reach = r + 1.0;
        let px0 = ((x0.min(x1) - reach).floor().max(0.0)) as usize;
        let py0 = ((y0.min(y1) - reach).floor().max(0.0)) as usize;
        let px1 = ((x0.max(x1) + reach).ceil() as usize).min(w);
        let py1 = ((y0.max(y1) + reach).ceil() as usize).min(h);
        for py in py0..py1 {
            for px in px0..px1 {
                let d = segment_distance((px as f32 + 0.5, py as f32 + 0.5), (x0, y0), (x1, y1));
                let c = (r + 0.5 - d).clamp(0.0, 1.0);
                if c > 0.0 {
                    let p = py * w + px;
                    cover[p] = cover[p].max(c);
                    top[p] = top[p].max(order);
                }
            }
        }
    }
    for p in 0..w * h {
        if cover[p] <= 0.0 {
            continue;
        }
        let t = if max_order > 1 {
            f32::from(top[p] - 1) / f32::from(max_order - 1)
        } else {
            0.0
        };
        for k in 0..3 {
            let blue = LOW[k] + t * (HIGH[k] - LOW[k]);
            let v = f32::from(rgb[3 * p + k]);
            rgb[3 * p + k] = (v + cover[p] * (blue - v)).round().clamp(0.0, 255.0) as u8;
        }
    }
    Ok((w, h, rgb))
}

/// Distance from `p` to the segment `a`-`b`.
fn segment_distance(p: (f32, f32), a: (f32, f32), b: (f32, f32)) -> f32 {
    let (vx, vy) = (b.0 - a.0, b.1 - a.1);
    let len2 = vx * vx + vy * vy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * vx + (p.1 - a.1) * vy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.0 - a.0 - t * vx).hypot(p.1 - a.1 - t * vy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A channel running east along the middle row is drawn blue on its row and its width
    /// grows with the order.
    #[test]
    fn channels_are_blue_and_wider_with_order() {
        let (w, h) = (32, 17);
        let dem = Heightfield::from_fn(w, h, 10.0, 10.0, |x, y| 100.0 + x as f32 + y as f32);
        let dir = dem.with_data(vec![1.0; w * h]).unwrap();
        let painted = |order: f32| {
            let mut s = vec![0f32; w * h];
            for x in 0..w - 1 {
                s[8 * w + x] = order;
            }
            let rgb = channel_map(&dem, &dir, &dem.with_data(s).unwrap()).unwrap();
            let blue_rows = (0..h)
                .filter(|&y| {
                    let p = 3 * (y * w + w / 2);
                    rgb[p + 2] > 150 && rgb[p + 2] > rgb[p] + 60
                })
                .count();
            (rgb, blue_rows)
        };
        let (rgb, thin) = painted(1.0);
        let p = 3 * (8 * w + w / 2);
        assert!(
            rgb[p + 2] > rgb[p] && rgb[p + 2] > rgb[p + 1],
            "{:?}",
            &rgb[p..p + 3]
        );
        let q = 3 * (2 * w + w / 2);
        assert!(
            rgb[q + 2] <= rgb[q] + 30,
            "far from the channel: {:?}",
            &rgb[q..q + 3]
        );
        let (_, thick) = painted(5.0);
        assert!(thick > thin, "order 5: {thick} rows, order 1: {thin}");
        // At most 16 pixels a side: halved, the channel on the middle row (row 4 of 8).
        let mut s = vec![0f32; w * h];
        for x in 0..w - 1 {
            s[8 * w + x] = 1.0;
        }
        let s = dem.with_data(s).unwrap();
        let (sw, sh, rgb) = channel_map_within(&dem, &dir, &s, 16).unwrap();
        assert_eq!((sw, sh), (16, 8));
        let p = 3 * (4 * sw + sw / 2);
        assert!(rgb[p + 2] > rgb[p] + 60, "{:?}", &rgb[p..p + 3]);
    }
}
