//! Filter: how an engine reconstructs the lightmap between texel centres,
//! and so what the texels are fitted for (`--filter`).
//!
//! In: a lookup's UV (glTF conventions: texel (i, j) of a W x H page has
//! its centre at ((i + 0.5) / W, (j + 0.5) / H), clamp to edge). Out: the
//! texels it reads and their weights ([`Filter::taps`]).
//!
//! - [`Filter::Bilinear`]: the GPU's bilinear lookup, 2 x 2 taps. The
//!   texels are the signal at their centres, fitted to surface points
//!   only where the bilinear ramp between centres misplaces it (the border
//!   band and the step cells: [`super::border`]).
//! - [`Filter::Bicubic`]: the uniform cubic B-spline engines offer as
//!   "bicubic" lightmap sampling (Godot's LightmapGI, Bevy's
//!   `Lightmap::bicubic_sampling`, Unity's bicubic lightmaps), 4 x 4 taps.
//!   The B-spline does not interpolate: a texel is a coefficient, not the
//!   signal at its centre, so every texel a surface lookup reads is
//!   solved for (Unser, "Splines: a perfect fit for signal and image
//!   processing", 1999, for the interpolating coefficients; here a least
//!   squares over the chart, [`super::build`]).

use serde::{Deserialize, Serialize};

/// The lookup the texels are fitted for, recorded in the file
/// (`filter` of the root's `AOBAKE_lightmap`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum Filter {
    #[default]
    Bilinear,
    Bicubic,
}

/// The texels of one lookup and their weights (at most 16).
#[derive(Clone, Copy, Debug)]
pub struct Taps {
    taps: [(u32, f32); 16],
    len: u8,
}

impl Taps {
    pub fn as_slice(&self) -> &[(u32, f32)] {
        &self.taps[..self.len as usize]
    }

    pub fn iter(&self) -> std::slice::Iter<'_, (u32, f32)> {
        self.as_slice().iter()
    }
}

impl IntoIterator for Taps {
    type Item = (u32, f32);
    type IntoIter = std::iter::Take<std::array::IntoIter<(u32, f32), 16>>;
    fn into_iter(self) -> Self::IntoIter {
        self.taps.into_iter().take(self.len as usize)
    }
}

/// The four texels and weights of a bilinear lookup at `uv` (glTF
/// conventions, clamp to edge).
#[inline]
pub fn bilinear_taps(uv: [f32; 2], width: u32, height: u32) -> [(u32, f32); 4] {
    let x = uv[0] * width as f32 - 0.5;
    let y = uv[1] * height as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let clamp = |v: f32, n: u32| (v.max(0.0) as u32).min(n - 1);
    let (xa, xb) = (clamp(x0, width), clamp(x0 + 1.0, width));
    let (ya, yb) = (clamp(y0, height), clamp(y0 + 1.0, height));
    [
        (ya * width + xa, (1.0 - fx) * (1.0 - fy)),
        (ya * width + xb, fx * (1.0 - fy)),
        (yb * width + xa, (1.0 - fx) * fy),
        (yb * width + xb, fx * fy),
    ]
}

/// The uniform cubic B-spline's four weights at fraction `t` in [0, 1)
/// past the second tap's centre (they sum to 1; at t = 0: 1/6, 4/6, 1/6, 0).
#[inline]
pub(crate) fn bspline_weights(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    let s = 1.0 - t;
    [
        s * s * s / 6.0,
        (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t3 / 6.0,
    ]
}

impl Filter {
    /// The texels and weights of a lookup at `uv` of a `width` x `height`
    /// page (clamp to edge: a tap past the page reads its edge texel).
    #[inline]
    pub fn taps(self, uv: [f32; 2], width: u32, height: u32) -> Taps {
        let mut out = Taps {
            taps: [(0, 0.0); 16],
            len: 0,
        };
        match self {
            Filter::Bilinear => {
                for (k, tap) in bilinear_taps(uv, width, height).into_iter().enumerate() {
                    out.taps[k] = tap;
                }
                out.len = 4;
            }
            Filter::Bicubic => {
                let x = uv[0] * width as f32 - 0.5;
                let y = uv[1] * height as f32 - 0.5;
                let (x1, y1) = (x.floor(), y.floor());
                let (wx, wy) = (bspline_weights(x - x1), bspline_weights(y - y1));
                let clamp = |v: f32, n: u32| (v.max(0.0) as u32).min(n - 1);
                let mut k = 0;
                for (j, wy) in wy.iter().enumerate() {
                    let row = clamp(y1 - 1.0 + j as f32, height) * width;
                    for (i, wx) in wx.iter().enumerate() {
                        let col = clamp(x1 - 1.0 + i as f32, width);
                        out.taps[k] = (row + col, wx * wy);
                        k += 1;
                    }
                }
                out.len = 16;
            }
        }
        out
    }

    /// The lookup at `uv` of an image of `N` channels per texel.
    #[inline]
    pub fn lookup<const N: usize>(
        self,
        image: &[[f32; N]],
        width: u32,
        height: u32,
        uv: [f32; 2],
    ) -> [f32; N] {
        let mut out = [0.0; N];
        for (t, w) in self.taps(uv, width, height) {
            for (o, x) in out.iter_mut().zip(&image[t as usize]) {
                *o += w * x;
            }
        }
        out
    }

    /// The lookup at `uv` of a one-channel image.
    #[inline]
    pub fn lookup1(self, image: &[f32], width: u32, height: u32, uv: [f32; 2]) -> f32 {
        (self.taps(uv, width, height).iter())
            .map(|&(t, w)| w * image[t as usize])
            .sum()
    }

    /// Texels (Chebyshev) a lookup reaches from the cell holding it: 1 for
    /// bilinear, 2 for bicubic.
    pub fn reach(self) -> u32 {
        match self {
            Filter::Bilinear => 1,
            Filter::Bicubic => 2,
        }
    }

    pub fn is_bilinear(&self) -> bool {
        *self == Filter::Bilinear
    }

    /// The contract's name of the filter.
    pub fn name(self) -> &'static str {
        match self {
            Filter::Bilinear => "bilinear",
            Filter::Bicubic => "bicubic",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taps_follow_the_gltf_texel_centres() {
        // The centre of texel (1, 2) of a 4 x 4 page: all weight on it.
        let t = bilinear_taps([1.5 / 4.0, 2.5 / 4.0], 4, 4);
        let on: f32 = t.iter().filter(|(i, _)| *i == 2 * 4 + 1).map(|x| x.1).sum();
        assert!((on - 1.0).abs() < 1e-6, "{t:?}");
        // Half-way between texels 0 and 1 of row 0, on the row's centre.
        let t = bilinear_taps([1.0 / 4.0, 0.5 / 4.0], 4, 4);
        let w = |i: u32| t.iter().filter(|x| x.0 == i).map(|x| x.1).sum::<f32>();
        assert!((w(0) - 0.5).abs() < 1e-6 && (w(1) - 0.5).abs() < 1e-6);
        // Outside the page: clamped to the edge texel.
        let t = bilinear_taps([-0.3, 1.2], 4, 4);
        assert!(t.iter().all(|x| x.0 == 12 || x.1 == 0.0), "{t:?}");
        assert!((t.iter().map(|x| x.1).sum::<f32>() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn bspline_weights_are_the_closed_form() {
        // At t = 0 the spline at a texel centre: 1/6, 4/6, 1/6, 0.
        let w = bspline_weights(0.0);
        for (a, b) in w.iter().zip([1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0, 0.0]) {
            assert!((a - b).abs() < 1e-7, "{w:?}");
        }
        // Half way: 1/48, 23/48, 23/48, 1/48.
        let w = bspline_weights(0.5);
        for (a, b) in w.iter().zip([1.0, 23.0, 23.0, 1.0]) {
            assert!((a - b / 48.0).abs() < 1e-7, "{w:?}");
        }
        for t in [0.1f32, 0.37, 0.9] {
            assert!((bspline_weights(t).iter().sum::<f32>() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn bicubic_reads_a_linear_ramp_exactly_and_a_constant_at_the_edge() {
        // The cubic B-spline reproduces linear functions: coefficients
        // x_i = i read back the ramp u * W - 0.5 away from the edges.
        let (w, h) = (8u32, 8u32);
        let img: Vec<f32> = (0..w * h).map(|t| (t % w) as f32).collect();
        for u in [2.5f32, 3.0, 3.3, 4.75] {
            let got = Filter::Bicubic.lookup1(&img, w, h, [u / w as f32, 0.4]);
            assert!((got - (u - 0.5)).abs() < 1e-5, "{u}: {got}");
        }
        // Clamped to the edge: a constant image reads its constant anywhere.
        let flat = vec![0.25f32; 64];
        for uv in [[-0.2f32, 0.0], [0.99, 1.3], [0.5, 0.5]] {
            let got = Filter::Bicubic.lookup1(&flat, w, h, uv);
            assert!((got - 0.25).abs() < 1e-6, "{uv:?}");
        }
        // Bilinear is the 2 x 2 lookup.
        assert_eq!(Filter::Bilinear.taps([0.3, 0.3], w, h).as_slice().len(), 4);
    }
}
