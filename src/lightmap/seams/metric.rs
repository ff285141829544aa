//! Metric: how far the two sides of the seams disagree.
//!
//! In: the [`Seam`]s of a page, its size, the AO and SH images (row-major,
//! row 0 at the top, as the textures). Out: [`SeamFigures`]: along every
//! seam, points two per texel of its UV length (at least three), each side
//! looked up bilinearly with the glTF conventions (texel centres at
//! ((i + 0.5) / W, (j + 0.5) / H), clamp to edge), the absolute AO
//! difference and the RMS over the 9 SH coefficients, weighted by world
//! length: mean, 95th percentile and the share of length over one 8-bit
//! step (8/255 is what a viewer sees as a line).

use super::find::Seam;
use crate::lightmap::filter::Filter;
use crate::sh::SH_COUNT;
use rayon::prelude::*;
use serde::Serialize;

/// Sample parameters along a seam: `per_texel` per texel of its longer
/// side's UV length, at least three, at the centres of equal parts.
pub fn samples(seam: &Seam, width: u32, height: u32, per_texel: f32) -> impl Iterator<Item = f32> {
    let count = ((seam.texels(width, height) * per_texel).ceil() as usize).max(3);
    (0..count).map(move |k| (k as f32 + 0.5) / count as f32)
}

/// The seam figures of one state of the page.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct SeamFigures {
    /// Mean |AO jump| over the seams' length.
    pub ao_mean: f64,
    pub ao_p95: f64,
    /// Share of seam length where the AO jumps by more than 8/255.
    pub ao_over_8bit: f64,
    /// Mean over the length of the RMS jump of the 9 SH coefficients.
    pub sh_rms_mean: f64,
}

/// One point of the metric on a seam: its UV on each side, the jumps
/// there and its share of the seams' length.
#[derive(Clone, Copy, Debug)]
pub struct SeamPoint {
    pub a: [f32; 2],
    pub b: [f32; 2],
    /// |AO difference| of the two sides' lookups.
    pub ao_jump: f64,
    /// RMS over the 9 SH coefficients of the difference.
    pub sh_rms: f64,
    /// Length weight (bake units).
    pub weight: f64,
}

/// The metric's points of `seams` on images `ao` and `sh` of `width` x
/// `height`: two per texel of each seam's UV length, at least three.
pub fn points(
    seams: &[Seam],
    width: u32,
    height: u32,
    ao: &[f32],
    sh: &[[f32; SH_COUNT]],
    filter: Filter,
) -> Vec<SeamPoint> {
    let look = |uv: [f32; 2]| {
        let mut a = 0.0f64;
        let mut s = [0.0f64; SH_COUNT];
        for (t, w) in filter.taps(uv, width, height) {
            a += w as f64 * ao[t as usize] as f64;
            for (s, c) in s.iter_mut().zip(sh[t as usize]) {
                *s += w as f64 * c as f64;
            }
        }
        (a, s)
    };
    seams
        .par_iter()
        .flat_map_iter(|seam| {
            let n = samples(seam, width, height, 2.0).count();
            let weight = seam.length as f64 / n as f64;
            samples(seam, width, height, 2.0).map(move |t| {
                let (a, b) = seam.at(t);
                let ((aa, sa), (ab, sb)) = (look(a), look(b));
                let sh_rms = (sa
                    .iter()
                    .zip(&sb)
                    .map(|(x, y)| (x - y).powi(2))
                    .sum::<f64>()
                    / SH_COUNT as f64)
                    .sqrt();
                SeamPoint {
                    a,
                    b,
                    ao_jump: (aa - ab).abs(),
                    sh_rms,
                    weight,
                }
            })
        })
        .collect()
}

/// [`SeamFigures`] of `seams` on images `ao` and `sh` of `width` x `height`.
pub fn measure(
    seams: &[Seam],
    width: u32,
    height: u32,
    ao: &[f32],
    sh: &[[f32; SH_COUNT]],
    filter: Filter,
) -> SeamFigures {
    summarise(&points(seams, width, height, ao, sh, filter))
}

/// [`SeamFigures`] of the metric's points: length-weighted mean, p95 and
/// share over 8/255.
pub(crate) fn summarise(points: &[SeamPoint]) -> SeamFigures {
    // (AO jump, SH RMS jump, length weight) per sample point.
    let mut points: Vec<(f64, f64, f64)> = points
        .iter()
        .map(|p| (p.ao_jump, p.sh_rms, p.weight))
        .collect();
    let total: f64 = points.iter().map(|p| p.2).sum();
    if total <= 0.0 {
        return SeamFigures::default();
    }
    let ao_mean = points.iter().map(|p| p.0 * p.2).sum::<f64>() / total;
    let sh_rms_mean = points.iter().map(|p| p.1 * p.2).sum::<f64>() / total;
    let ao_over_8bit = points
        .iter()
        .filter(|p| p.0 > 8.0 / 255.0)
        .map(|p| p.2)
        .sum::<f64>()
        / total;
    points.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut acc = 0.0;
    let mut ao_p95 = points.last().map_or(0.0, |p| p.0);
    for p in &points {
        acc += p.2;
        if acc >= 0.95 * total {
            ao_p95 = p.0;
            break;
        }
    }
    SeamFigures {
        ao_mean,
        ao_p95,
        ao_over_8bit,
        sh_rms_mean,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_image_has_no_jump_and_a_step_has_its_height() {
        let (w, h) = (8, 8);
        let seam = Seam {
            a: [[0.1, 0.1], [0.1, 0.9]],
            b: [[0.9, 0.1], [0.9, 0.9]],
            length: 2.0,
        };
        let flat = vec![0.5f32; 64];
        let sh = vec![[0.1f32; SH_COUNT]; 64];
        let f = measure(&[seam], w, h, &flat, &sh, Filter::Bilinear);
        assert!(
            f.ao_mean < 1e-6 && f.ao_p95 < 1e-6 && f.sh_rms_mean < 1e-6,
            "{f:?}"
        );
        assert_eq!(f.ao_over_8bit, 0.0);
        // The right half 0.2 brighter: every point jumps by 0.2.
        let step: Vec<f32> = (0..64)
            .map(|t| if t % 8 >= 4 { 0.7 } else { 0.5 })
            .collect();
        let f = measure(&[seam], w, h, &step, &sh, Filter::Bilinear);
        assert!((f.ao_mean - 0.2).abs() < 1e-6 && (f.ao_p95 - 0.2).abs() < 1e-6);
        assert_eq!(f.ao_over_8bit, 1.0);
    }
}
