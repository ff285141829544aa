//! Encode: per-receiver results into lightmap images.
//!
//! In: a page's float [`Lightmap`] (from the lightmap stage,
//! [`crate::lightmap`]). Out: its [`Encoded`] form per the output contract: AO as an 8-bit grey PNG, SH as three RGBA8
//! PNGs with per-coefficient scale and offset (`c_i = shScale[i] * channel_i +
//! shOffset[i]`; c0..c3 = T0.rgba, c4..c7 = T1.rgba, c8 = T2.r). Optionally a
//! float EXR with channels `ao`, `sh0`..`sh8` (and `v0`..`v15` with the
//! visibility layer). The visibility layer, when baked, is encoded the same
//! way into 4 RGBA8 PNGs (3 at order 2) with its own scale and offset.

use crate::atlas::Receivers;
use crate::bake::adaptive::Scale;
use crate::error::{Error, Result};
use crate::lightmap::Lightmap;
use crate::lightmap::seams::SolveRange;
use crate::sh::{SH_COUNT, VIS_COUNT};
use image::ImageEncoder;
use rayon::prelude::*;
use std::path::Path;

/// The contract's encoded images.
#[derive(Clone, Debug, PartialEq)]
pub struct Encoded {
    pub occlusion_png: Vec<u8>,
    pub sh_png: [Vec<u8>; 3],
    pub sh_scale: [f32; SH_COUNT],
    pub sh_offset: [f32; SH_COUNT],
    pub visibility: Option<EncodedVisibility>,
    /// The adaptive allocation's page scale the page was baked with (not
    /// an image: recorded in the fingerprint for a later `--reuse`).
    pub scale: Option<Scale>,
    /// The range the lightmap stage's solve kept the page in (not an
    /// image: recorded in the fingerprint for a later `--reuse`).
    pub solve_range: Option<SolveRange>,
    /// The page's receivers inside geometry, as runs of texels
    /// `[first, count, ...]` in row-major order (not an image: recorded in
    /// the fingerprint for a later `--reuse`; `None`: not recorded).
    pub inside: Option<Vec<u32>>,
}

/// Each channel's scale and offset, taken from an earlier bake of the
/// page (`--reuse`) instead of the page's own range: a value outside them
/// is written clamped.
#[derive(Clone, Debug, PartialEq)]
pub struct Ranges {
    pub sh_scale: [f32; SH_COUNT],
    pub sh_offset: [f32; SH_COUNT],
    /// The visibility layer's, when it has one.
    pub visibility: Option<(Vec<f32>, Vec<f32>)>,
}

/// The visibility layer's images: `png[k]` holds v_{4k}..v_{4k+3} in
/// RGBA, v_i = scale\[i\] x channel_i + offset\[i\].
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedVisibility {
    pub png: Vec<Vec<u8>>,
    pub scale: Vec<f32>,
    pub offset: Vec<f32>,
}

/// An 8-bit PNG of `data` (rows top to bottom) in the given colour type.
pub fn png(
    width: u32,
    height: u32,
    data: &[u8],
    color: image::ExtendedColorType,
) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(data, width, height, color)
        .map_err(|e| Error::Encode(e.to_string()))?;
    Ok(out)
}

/// An 8-bit grey PNG in the atlas layout: each receiver's texel shows
/// `value(receiver)` (0..1 to black..white), uncovered texels are black.
pub fn grey_map(receivers: &Receivers, value: impl Fn(usize) -> f32) -> Result<Vec<u8>> {
    let mut img = vec![0u8; (receivers.width * receivers.height) as usize];
    for (r, &t) in receivers.texel.iter().enumerate() {
        img[t as usize] = to_u8(value(r));
    }
    png(
        receivers.width,
        receivers.height,
        &img,
        image::ExtendedColorType::L8,
    )
}

#[inline]
fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The byte a coefficient is written as: `(v - offset) / scale` on [0,
/// 255], clamped; 0 for a channel whose range is empty (`scale` 0).
#[inline]
pub fn to_byte(v: f32, scale: f32, offset: f32) -> u8 {
    if scale > 0.0 {
        to_u8((v - offset) / scale)
    } else {
        0
    }
}

/// The value a byte is read as: `scale x q / 255 + offset` (the contract's
/// decoding; AO is scale 1, offset 0).
#[inline]
pub fn from_byte(q: u8, scale: f32, offset: f32) -> f32 {
    scale * (q as f32 / 255.0) + offset
}

/// One of the encoded PNGs, decoded.
pub(crate) fn read_png(png: &[u8]) -> Result<image::DynamicImage> {
    image::load_from_memory_with_format(png, image::ImageFormat::Png)
        .map_err(|err| Error::Encode(format!("an encoded PNG does not decode: {err}")))
}

/// Scale and offset mapping each coefficient's range onto [0, 1].
pub(crate) fn sh_range<const N: usize>(sh: &[[f32; N]]) -> ([f32; N], [f32; N]) {
    let mut lo = [f32::INFINITY; N];
    let mut hi = [f32::NEG_INFINITY; N];
    for c in sh {
        for i in 0..N {
            lo[i] = lo[i].min(c[i]);
            hi[i] = hi[i].max(c[i]);
        }
    }
    let mut scale = [0.0; N];
    let mut offset = [0.0; N];
    for i in 0..N {
        if lo[i].is_finite() {
            offset[i] = lo[i];
            scale[i] = hi[i] - lo[i];
        }
    }
    (scale, offset)
}

/// The RGBA8 channels of the first `count` coefficients of `values`, 4 per
/// page (`channel_i = (c_i - offset_i) / scale_i`; a page's unused
/// channels hold 0, 0, 255), with the scale and offset of each.
#[allow(clippy::type_complexity)]
fn rgba_channels<const N: usize>(
    values: &[[f32; N]],
    count: usize,
    range: Option<([f32; N], [f32; N])>,
) -> (Vec<Vec<u8>>, [f32; N], [f32; N]) {
    let (scale, offset) = range.unwrap_or_else(|| sh_range(values));
    let channel = |c: &[f32; N], i: usize| to_byte(c[i], scale[i], offset[i]);
    let pages = (0..count.div_ceil(4))
        .into_par_iter()
        .map(|p| {
            values
                .par_iter()
                .flat_map_iter(|c| {
                    (0..4).map(move |k| {
                        let i = p * 4 + k;
                        if i < count {
                            channel(c, i)
                        } else if k == 3 {
                            255
                        } else {
                            0
                        }
                    })
                })
                .collect()
        })
        .collect();
    (pages, scale, offset)
}

/// Encodes the lightmap per the output contract; the visibility layer, if
/// any, to `visibility_order` (2: 9 coefficients, 3: 16).
pub fn encode(lm: &Lightmap, visibility_order: u32) -> Result<Encoded> {
    encode_in(lm, visibility_order, None)
}

/// [`encode`], each channel on `ranges` when given (a layer whose carried
/// range does not have its coefficient count gets its own).
pub fn encode_in(lm: &Lightmap, visibility_order: u32, ranges: Option<&Ranges>) -> Result<Encoded> {
    let (w, h) = (lm.width, lm.height);
    let count = ((visibility_order + 1) * (visibility_order + 1)) as usize;
    let count = count.min(VIS_COUNT);
    // Channels first, then every image compressed on a thread of its own.
    let ao: Vec<u8> = lm.ao.par_iter().map(|&a| to_u8(a)).collect();
    let sh_range = ranges.map(|r| (r.sh_scale, r.sh_offset));
    let (sh, sh_scale, sh_offset) = rgba_channels(&lm.sh, SH_COUNT, sh_range);
    let layer_range = (ranges.and_then(|r| r.visibility.as_ref()))
        .filter(|(scale, offset)| scale.len() == count && offset.len() == count)
        .map(|(scale, offset)| {
            let pad = |v: &[f32]| std::array::from_fn(|i| v.get(i).copied().unwrap_or(0.0));
            (pad(scale), pad(offset))
        });
    let layer = lm
        .visibility
        .as_ref()
        .map(|v| rgba_channels(v, count, layer_range));
    let mut images: Vec<(&[u8], image::ExtendedColorType)> =
        vec![(&ao, image::ExtendedColorType::L8)];
    images.extend(
        sh.iter()
            .map(|c| (c.as_slice(), image::ExtendedColorType::Rgba8)),
    );
    if let Some((v, _, _)) = &layer {
        images.extend(
            v.iter()
                .map(|c| (c.as_slice(), image::ExtendedColorType::Rgba8)),
        );
    }
    let mut pngs = images
        .par_iter()
        .map(|&(data, color)| png(w, h, data, color))
        .collect::<Result<Vec<_>>>()?
        .into_iter();
    let occlusion_png = pngs.next().expect("the AO image");
    let sh_png: [Vec<u8>; 3] = [0; 3].map(|_| pngs.next().expect("3 SH images"));
    let visibility = layer.map(|(_, scale, offset)| EncodedVisibility {
        png: pngs.collect(),
        scale: scale[..count].to_vec(),
        offset: offset[..count].to_vec(),
    });
    Ok(Encoded {
        occlusion_png,
        sh_png,
        sh_scale,
        sh_offset,
        visibility,
        scale: None,
        solve_range: None,
        inside: None,
    })
}

/// The images as an engine reads them: every PNG decoded, each 8-bit
/// channel mapped back through its scale and offset (`c_i = scale_i x
/// channel_i / 255 + offset_i`, AO = channel / 255). The inverse of
/// [`encode`] up to 8-bit quantization; `covered` is left empty.
pub fn decode(e: &Encoded) -> Result<Lightmap> {
    let ao = read_png(&e.occlusion_png)?.into_luma8();
    let (width, height) = ao.dimensions();
    let sh_images = e
        .sh_png
        .iter()
        .map(|p| Ok(read_png(p)?.into_rgba8().into_raw()))
        .collect::<Result<Vec<_>>>()?;
    let n = (width * height) as usize;
    let sh = (0..n)
        .map(|t| {
            std::array::from_fn(|i| {
                from_byte(
                    sh_images[i / 4][t * 4 + i % 4],
                    e.sh_scale[i],
                    e.sh_offset[i],
                )
            })
        })
        .collect();
    let visibility = match &e.visibility {
        Some(v) => {
            let images = (v.png.iter())
                .map(|p| Ok(read_png(p)?.into_rgba8().into_raw()))
                .collect::<Result<Vec<_>>>()?;
            Some(
                (0..n)
                    .map(|t| {
                        std::array::from_fn(|i| match v.scale.get(i) {
                            Some(&s) => from_byte(images[i / 4][t * 4 + i % 4], s, v.offset[i]),
                            None => 0.0,
                        })
                    })
                    .collect(),
            )
        }
        None => None,
    };
    Ok(Lightmap {
        width,
        height,
        ao: ao
            .into_raw()
            .into_iter()
            .map(|q| from_byte(q, 1.0, 0.0))
            .collect(),
        sh,
        covered: Vec::new(),
        visibility,
    })
}

/// Writes `ao` and `sh0`..`sh8` as 32-bit float channels of one EXR layer.
pub(crate) fn write_exr(lm: &Lightmap, path: &Path) -> Result<()> {
    use exr::prelude::*;
    let mut chans: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    chans.push(AnyChannel::new("ao", FlatSamples::F32(lm.ao.clone())));
    for i in 0..SH_COUNT {
        chans.push(AnyChannel::new(
            format!("sh{i}").as_str(),
            FlatSamples::F32(lm.sh.iter().map(|c| c[i]).collect()),
        ));
    }
    if let Some(v) = &lm.visibility {
        for i in 0..VIS_COUNT {
            chans.push(AnyChannel::new(
                format!("v{i}").as_str(),
                FlatSamples::F32(v.iter().map(|c| c[i]).collect()),
            ));
        }
    }
    let layer = Layer::new(
        (lm.width as usize, lm.height as usize),
        LayerAttributes::named("lightmap"),
        Encoding::SMALL_FAST_LOSSLESS,
        AnyChannels::sort(chans),
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| crate::error::Error::Encode(format!("{}: {e}", path.display())))
}

/// Writes per-receiver diagnostic maps into `dir`, each as `NAME.png`
/// ([`grey_map`]: values in [0, 1], white = 1, gutters black). Each method
/// says what its maps show (for the filtered method,
/// [`crate::bake::sheared::ShearedStats::debug_maps`]).
pub(crate) fn write_grey_maps(
    dir: &Path,
    receivers: &Receivers,
    maps: &[(&str, Vec<f32>)],
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    for (name, values) in maps {
        let bytes = grey_map(receivers, |r| values[r])?;
        crate::file::write_atomic(&dir.join(format!("{name}.png")), &bytes)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sh_range_maps_extremes_to_0_and_1() {
        let sh = vec![[0.5; SH_COUNT], [-0.25; SH_COUNT], [0.1; SH_COUNT]];
        let (s, o) = sh_range(&sh);
        for i in 0..SH_COUNT {
            assert!((o[i] + 0.25).abs() < 1e-7 && (s[i] - 0.75).abs() < 1e-7);
        }
        let (s, o) = sh_range(&[[0.3; SH_COUNT]]);
        assert!(s.iter().all(|&v| v == 0.0) && o.iter().all(|&v| (v - 0.3).abs() < 1e-7));
    }

    #[test]
    fn decode_inverts_encode_within_half_a_step() {
        let (w, h) = (5u32, 3u32);
        let n = (w * h) as usize;
        let value =
            |t: usize, i: usize| ((t * 7 + i * 3) % 11) as f32 / 10.0 - 0.4 * (i % 2) as f32;
        let lm = Lightmap {
            width: w,
            height: h,
            ao: (0..n).map(|t| t as f32 / n as f32).collect(),
            sh: (0..n)
                .map(|t| std::array::from_fn(|i| value(t, i)))
                .collect(),
            covered: vec![true; n],
            visibility: Some(
                (0..n)
                    .map(|t| std::array::from_fn(|i| value(t, i + 1)))
                    .collect(),
            ),
        };
        for order in [2, 3] {
            let back = decode(&encode(&lm, order).unwrap()).unwrap();
            assert_eq!((back.width, back.height), (w, h));
            let e = encode(&lm, order).unwrap();
            for t in 0..n {
                assert!((back.ao[t] - lm.ao[t]).abs() <= 0.5 / 255.0 + 1e-6);
                for i in 0..SH_COUNT {
                    let step = e.sh_scale[i] / 255.0;
                    assert!((back.sh[t][i] - lm.sh[t][i]).abs() <= 0.5 * step + 1e-6);
                }
                let (v, bv) = (
                    &lm.visibility.as_ref().unwrap()[t],
                    &back.visibility.as_ref().unwrap()[t],
                );
                let count = ((order + 1) * (order + 1)) as usize;
                for i in 0..VIS_COUNT {
                    if i < count {
                        let step = e.visibility.as_ref().unwrap().scale[i] / 255.0;
                        assert!((bv[i] - v[i]).abs() <= 0.5 * step + 1e-6);
                    } else {
                        assert_eq!(bv[i], 0.0);
                    }
                }
            }
        }
    }
}
