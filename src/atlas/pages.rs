//! Pages: the atlas's pages and the charted meshes on them.
//!
//! In: the packed charts (`uvunwrap`'s atlas, or its meshes as
//! [`ChartedMesh`]es). Out: the types of a page ([`PageSize`]) and of a
//! mesh's charts on the pages ([`ChartedMesh`]); the last of several pages
//! cropped to what its charts use ([`crop_last_page`]), and the chart that
//! fits no page with the density that would fit it ([`largest_chart`]).

/// One receiver mesh in the atlas.
#[derive(Clone, Debug, Default)]
pub struct ChartedMesh {
    /// Input vertex of each new vertex.
    pub xref: Vec<u32>,
    /// Atlas coordinate of each new vertex.
    pub uv: Vec<[f32; 2]>,
    /// Triangle list over the new vertices, same order as the input.
    pub triangles: Vec<u32>,
    /// Page of each triangle (a chart, and so each triangle, lies on one).
    pub triangle_page: Vec<u32>,
}

impl ChartedMesh {
    /// The pages this mesh has triangles on, ascending.
    pub fn pages(&self) -> Vec<u32> {
        let mut p = self.triangle_page.clone();
        p.sort_unstable();
        p.dedup();
        p
    }

    /// The triangles on `page` only (vertices kept, so `xref` and `uv` are
    /// shared with the whole mesh).
    pub(crate) fn on_page(&self, page: u32) -> ChartedMesh {
        let triangles: Vec<u32> = self
            .triangles
            .chunks_exact(3)
            .zip(&self.triangle_page)
            .filter(|&(_, &p)| p == page)
            .flat_map(|(t, _)| t.iter().copied())
            .collect();
        ChartedMesh {
            xref: self.xref.clone(),
            uv: self.uv.clone(),
            triangle_page: vec![0; triangles.len() / 3],
            triangles,
        }
    }

    /// The triangles on `page` with only the vertices they use, in their
    /// first-use order (for a primitive split across pages).
    pub fn compact_page(&self, page: u32) -> ChartedMesh {
        let mut new_index = vec![u32::MAX; self.xref.len()];
        let mut out = ChartedMesh::default();
        for (t, _) in self
            .triangles
            .chunks_exact(3)
            .zip(&self.triangle_page)
            .filter(|&(_, &p)| p == page)
        {
            for &v in t {
                let slot = &mut new_index[v as usize];
                if *slot == u32::MAX {
                    *slot = out.xref.len() as u32;
                    out.xref.push(self.xref[v as usize]);
                    out.uv.push(self.uv[v as usize]);
                }
                out.triangles.push(*slot);
            }
            out.triangle_page.push(0);
        }
        out
    }
}

/// Size of one atlas page in texels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct PageSize {
    pub width: u32,
    pub height: u32,
}

/// A chart that fits no page at the asked density.
#[derive(Clone, Debug, PartialEq)]
pub struct ChartTooLarge {
    /// The receiver mesh it belongs to.
    pub mesh: usize,
    /// Its padded size in texels at the asked density.
    pub width: u32,
    pub height: u32,
    /// The largest texel density (world units) at which it fits a page.
    pub fitting_density: f64,
}

/// Crops the last of `count` `w` x `h` pages to the texels its charts use
/// (and their padding), rescaling its vertices' UVs to the smaller page.
/// Returns every page's size.
pub fn crop_last_page(
    meshes: &mut [ChartedMesh],
    w: u32,
    h: u32,
    count: u32,
    padding: u32,
) -> Vec<PageSize> {
    let last = count - 1;
    // Per mesh, its vertices on the last page.
    let on_last: Vec<Vec<bool>> = meshes
        .iter()
        .map(|m| {
            let mut used = vec![false; m.uv.len()];
            for (t, &p) in m.triangles.chunks_exact(3).zip(&m.triangle_page) {
                if p == last {
                    for &v in t {
                        used[v as usize] = true;
                    }
                }
            }
            used
        })
        .collect();
    let (mut max_u, mut max_v) = (0.0f32, 0.0f32);
    for (m, used) in meshes.iter().zip(&on_last) {
        for (uv, _) in m.uv.iter().zip(used).filter(|(_, u)| **u) {
            max_u = max_u.max(uv[0]);
            max_v = max_v.max(uv[1]);
        }
    }
    let crop = |max: f32, edge: u32| ((max * edge as f32).ceil() as u32 + padding).clamp(1, edge);
    let (cw, ch) = (crop(max_u, w), crop(max_v, h));
    for (m, used) in meshes.iter_mut().zip(&on_last) {
        for (uv, _) in m.uv.iter_mut().zip(used).filter(|(_, u)| **u) {
            uv[0] = uv[0] * w as f32 / cw as f32;
            uv[1] = uv[1] * h as f32 / ch as f32;
        }
    }
    let mut pages = vec![
        PageSize {
            width: w,
            height: h
        };
        count as usize
    ];
    pages[last as usize] = PageSize {
        width: cw,
        height: ch,
    };
    pages
}

/// The largest chart of an unbounded atlas: its mesh, padded size and the
/// world density at which it would fit a `page_size` page.
pub fn largest_chart(
    atlas: &uvunwrap::Atlas,
    padding: u32,
    page_size: u32,
    density: f64,
) -> ChartTooLarge {
    let (w, h) = (atlas.width as f32, atlas.height as f32);
    let mut best = ChartTooLarge {
        mesh: 0,
        width: 0,
        height: 0,
        fitting_density: density,
    };
    for (mi, m) in atlas.meshes.iter().enumerate() {
        let mut boxes: std::collections::HashMap<u32, [f32; 4]> = Default::default();
        for v in &m.vertices {
            if let Some(c) = v.chart {
                let b = boxes
                    .entry(c)
                    .or_insert([f32::MAX, f32::MAX, f32::MIN, f32::MIN]);
                b[0] = b[0].min(v.uv[0] * w);
                b[1] = b[1].min(v.uv[1] * h);
                b[2] = b[2].max(v.uv[0] * w);
                b[3] = b[3].max(v.uv[1] * h);
            }
        }
        for b in boxes.values() {
            let (cw, ch) = ((b[2] - b[0]).ceil() as u32, (b[3] - b[1]).ceil() as u32);
            if cw.max(ch) > best.width.max(best.height) {
                let inner = page_size.saturating_sub(2 * padding + 2).max(1) as f64;
                best = ChartTooLarge {
                    mesh: mi,
                    width: cw + 2 * padding,
                    height: ch + 2 * padding,
                    fitting_density: density * inner / cw.max(ch).max(1) as f64,
                };
            }
        }
    }
    best
}
