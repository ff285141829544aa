// Rays on the GPU: one invocation per ray, a stack traversal of a BVH2
// (obvhs's, flattened by flatten.rs), the nearer child first. Two entry
// points: `occluded` (a sure hit ends the ray) and `closest` (the
// nearest candidate, cut at the ray's cap).
//
// In: nodes (box, then first child or first triangle, and the leaf's
// triangle count: 0 for an inner node, whose children are adjacent),
// triangles in leaf order (obvhs's RtTriangle) with each one's index among
// the occluders, rays as the CPU traces them (origin already shifted back
// by SHIFT, the end t_max + SHIFT, unit direction, and for `closest` the
// cap: a hit beyond it is taken as a hit at it, Hit::cap in bvh.rs). A ray
// whose end is negative is blocked (the host answers it).
//
// Out: final answers where the GPU's rounding cannot decide them, else
// "unsure", for the host to trace on the CPU (gpu/mod.rs). The test here
// is the CPU's (obvhs's RtTriangle::intersect, both faces, on the same
// precomputed edges and normal, the same operations in the same order),
// but a GPU may fuse a multiply and an add where the CPU rounds twice, and
// on a ray through an edge that decides the answer. So each test bounds
// its rounding (`candidate`): a triangle is a candidate when the ray meets
// it within the margins (barycentrics above -BARY_MARGIN, t within
// T_MARGIN of the range, relative) or within the bound, whichever is
// wider, and a sure hit when it clears the bound inside the triangle and
// the range. Every triangle the CPU hits is a candidate here, and every
// sure hit a hit on the CPU.
// `occluded` writes two bits a ray (ANSWER_*: a sure hit; no candidate;
// else unsure), sixteen rays a word, ray i at bits 2 (i % 16) of word
// i / 16. `closest` writes answers[i] = the nearest candidate triangle
// (NONE for none; its distance the host's retest gives), its top bit set
// (UNSURE_BIT) when it is not a sure hit, or another occluder's candidate
// lies within WINDOW (relative) of it or within their rounding bounds
// below the cap (a near tie, which rounding or the CPU's traversal order
// decides), or the walk was left partial.
//
// The box test widens each box's exit by 2 gamma_3 (Ize 2013, "Robust BVH
// Ray Traversal") so rounding never culls a box the ray enters.

struct Node {
    lo: vec3<f32>,
    first: u32,
    hi: vec3<f32>,
    count: u32,
};

struct Tri {
    v0: vec4<f32>,
    e1: vec4<f32>, // v0 - v1
    e2: vec4<f32>, // v2 - v0
    ng: vec4<f32>, // e1 x e2
};

struct Ray {
    origin: vec4<f32>, // xyz: shifted back by SHIFT; w: t_max + SHIFT
    dir: vec4<f32>,    // xyz unit (no -0.0); w: the cap (closest only)
};

struct Params {
    count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
};

@group(0) @binding(0) var<storage, read> nodes: array<Node>;
@group(0) @binding(1) var<storage, read> tris: array<Tri>;
@group(0) @binding(2) var<storage, read> rays: array<Ray>;
@group(0) @binding(3) var<storage, read_write> answers: array<u32>;
@group(0) @binding(4) var<uniform> params: Params;
@group(0) @binding(5) var<storage, read> occluder: array<u32>;

const STACK: u32 = 64u;
// 1 + 2 gamma_3, gamma_n = n eps / (1 - n eps), eps = 2^-24.
const EXIT_WIDEN: f32 = 1.0000004;
// The CPU backend's shift (BOX_EPSILON_SHIFT in bvh.rs).
const SHIFT: f32 = 2e-4;
const NONE: u32 = 0xffffffffu;
const MISS: f32 = -1.0;
const INFINITY: f32 = 3.4e38;
// The triangle test's margins (see above): far beyond a fused
// multiply-add's rounding except at grazing angles, and thin enough that
// a candidate the CPU misses is rare.
const BARY_MARGIN: f32 = 1e-4;
const T_MARGIN: f32 = 1e-5;
// Two candidates nearer each other than this (relative) are a near tie.
const WINDOW: f32 = 1e-5;
// A hit this near the ray's start (bake units, past SHIFT) is never sure:
// AT_START in bvh.rs.
const AT_START: f32 = 1e-7;
// Occlusion answers (two bits a ray) and the closest hit's flag (the top
// bit of its triangle): see the header.
const ANSWER_MISS: u32 = 0u;
const ANSWER_HIT: u32 = 1u;
const ANSWER_UNSURE: u32 = 2u;
const UNSURE_BIT: u32 = 0x80000000u;

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    // In the CPU's order: (x + y) + z.
    return (a.x * b.x + a.y * b.y) + a.z * b.z;
}

// The CPU test's rounding, bounded: its u, v, w and t each lie within
// the bound below of the exact values, and so do this test's (a fused
// multiply-add rounds less, never more), so the two differ by at most
// twice it. SURE_GAMMA is 16 units of rounding where the operations chain
// at most 8 (a cross product, a dot product, the division): twice the
// chain, for the two tests. Higham's gamma_n = n eps bound; eps = 2^-24.
const SURE_GAMMA: f32 = 9.536743e-7;
// Four times the smallest normal f32: what flushing a product's subnormal
// result to zero (as GPUs may) can change a sum of three by.
const FLUSH: f32 = 4.7e-38;

// What a triangle's test says of a ray.
struct Test {
    // Where the ray meets it (either face) within the margins, else MISS.
    t: f32,
    // Whether the CPU's test surely hits it in (t_sure, t_max]: every
    // barycentric and both ends of the range clear the rounding bound.
    sure: bool,
    // The bound on t's rounding (either test's t lies within it of the
    // exact one); infinite where the determinant's sign is not sure (t is
    // then the range's start, unknown).
    err: f32,
};

// The triangle's test (the CPU's, with the margins) for the ray from o
// along d in [t_min, t_max]; a sure hit also lies beyond t_sure (a hit at
// the ray's very start goes to the CPU, whose traversal may not reach it)
// and before t_end, the ray's own end (t_max may reach past it).
fn candidate(tri: Tri, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, t_sure: f32, t_end: f32) -> Test {
    let c = tri.v0.xyz - o;
    // d x c as glam computes it.
    let r = vec3<f32>(d.y * c.z - c.y * d.z, d.z * c.x - c.z * d.x, d.x * c.y - c.x * d.y);
    let det = dot3(tri.ng.xyz, d);
    let nc = dot3(tri.ng.xyz, c);
    // The rounding bounds: each operand's magnitude through the same
    // operations (and FLUSH for products a GPU may flush to zero), the
    // division's relative error through |det|.
    let ad = abs(d);
    let ac = abs(c);
    let an = abs(tri.ng.xyz);
    let adet = abs(det);
    let det_err = SURE_GAMMA * dot(an, ad) + FLUSH;
    let nc_err = SURE_GAMMA * dot(an, ac) + FLUSH;
    if adet <= 2.0 * det_err {
        // The determinant's sign, or its being zero, is rounding's: the
        // CPU's test may hit where this one cannot tell. Only a ray that
        // stays off the triangle's plane beyond its range is a sure miss.
        if abs(nc) - nc_err > t_max * (adet + 2.0 * det_err) {
            return Test(MISS, false, 0.0);
        }
        return Test(max(t_min, 0.0), false, INFINITY);
    }
    let inv_det = 1.0 / det;
    let u = dot3(r, tri.e2.xyz) * inv_det;
    let v = dot3(r, tri.e1.xyz) * inv_det;
    let w = 1.0 - u - v;
    let t = nc * inv_det;
    let big_r = vec3<f32>(ad.y * ac.z + ac.y * ad.z, ad.z * ac.x + ac.z * ad.x, ad.x * ac.y + ac.x * ad.y);
    let scale = 1.0 / adet;
    let eu = (SURE_GAMMA * dot(big_r, abs(tri.e2.xyz)) + FLUSH) * scale + abs(u) * det_err * scale;
    let ev = (SURE_GAMMA * dot(big_r, abs(tri.e1.xyz)) + FLUSH) * scale + abs(v) * det_err * scale;
    let ew = eu + ev + SURE_GAMMA * (1.0 + abs(u) + abs(v));
    let et = nc_err * scale + abs(t) * det_err * scale;
    // A candidate within the margins or the bounds, whichever is wider.
    let inside = u >= -max(BARY_MARGIN, eu) && v >= -max(BARY_MARGIN, ev) && w >= -max(BARY_MARGIN, ew);
    let in_range = t >= min(t_min * (1.0 - T_MARGIN), t_min - et) && t <= max(t_max * (1.0 + T_MARGIN), t_max + et);
    if !(inside && in_range) {
        return Test(MISS, false, 0.0);
    }
    // Sure: the hit inside the triangle and the range by more than the
    // bounds (the determinant's sign is sure above). A NaN fails every
    // comparison: never sure.
    let sure = u > eu && v > ev && w > ew && t > t_sure + et && t < t_end - et;
    return Test(max(t, 0.0), sure, et);
}

// Where the ray enters the node's box within [0, t_end], else MISS.
fn enter_box(n: Node, o: vec3<f32>, inv: vec3<f32>, t_end: f32) -> f32 {
    let t0 = (n.lo - o) * inv;
    let t1 = (n.hi - o) * inv;
    let near = min(t0, t1);
    let far = max(t0, t1);
    let enter = max(max(near.x, near.y), max(near.z, 0.0));
    let leave = min(min(far.x, far.y), min(far.z, t_end)) * EXIT_WIDEN;
    return select(MISS, enter, enter <= leave);
}

struct Found {
    t: f32,
    tri: u32,
    // Whether the answer is final: for `occluded`, a sure hit or no
    // candidate at all; for `closest`, the nearest candidate is a sure hit
    // and no other occluder's candidate is near it (`near`).
    sure: bool,
};

// Whether two candidates' t are a near tie: nearer each other than
// WINDOW (relative) or than their rounding bounds together, so that the
// CPU's tests may order them otherwise.
fn near(a: f32, b: f32, err: f32) -> bool {
    return abs(a - b) <= max(WINDOW * max(a, b), err);
}

// The traversal both entry points share: with `any`, a sure hit ends the
// ray (t unused) and a candidate that is not sure leaves it unsure; else
// the nearest candidate, each candidate's t capped at `cap`.
fn traverse(ray: Ray, any: bool) -> Found {
    let end = ray.origin.w;
    var found = Found(end, NONE, true);
    let d = ray.dir.xyz;
    let o = ray.origin.xyz;
    let cap = ray.dir.w;
    // Zero components get a tiny stand-in: finite slabs, same side.
    let tiny = vec3<f32>(1e-20);
    let safe = select(d, select(tiny, -tiny, d < vec3<f32>(0.0)), abs(d) < tiny);
    let inv = 1.0 / safe;
    // How far candidates are looked for: past the nearest so far by the
    // tie window (past the ray's end by the margin).
    var reach = end * (1.0 + WINDOW);
    if enter_box(nodes[0], o, inv, reach) == MISS {
        return found;
    }
    // Another occluder's candidate within WINDOW of the nearest (closest),
    // or within their rounding bounds.
    var tied = false;
    // The nearest candidate's rounding bound on t.
    var found_err = 0.0;
    // A node left unvisited (the stack full): no miss is sure.
    var partial = false;
    // Nodes to visit with where the ray enters them: a node entered
    // beyond the reach since is skipped.
    var stack_node: array<u32, STACK>;
    var stack_enter: array<f32, STACK>;
    var top = 0u;
    var node = 0u;
    loop {
        let n = nodes[node];
        if n.count > 0u {
            for (var k = n.first; k < n.first + n.count; k++) {
                let hit = candidate(tris[k], o, d, SHIFT, reach, SHIFT + AT_START, end);
                if hit.t == MISS {
                    continue;
                }
                if any {
                    if hit.sure {
                        return Found(hit.t, k, true);
                    }
                    found.sure = false;
                    continue;
                }
                let t = min(hit.t, cap);
                let other = found.tri != NONE && occluder[k] != occluder[found.tri];
                if found.tri == NONE || t < found.t {
                    // The one it replaces, if near, is a tie of the new.
                    tied = other && found.t < cap && near(t, found.t, hit.err + found_err);
                    found = Found(t, k, hit.sure);
                    found_err = hit.err;
                    reach = min(found.t * (1.0 + WINDOW), reach);
                } else if other && t < cap && near(t, found.t, hit.err + found_err) {
                    tied = true;
                }
            }
        } else {
            let a = n.first;
            let ta = enter_box(nodes[a], o, inv, reach);
            let tb = enter_box(nodes[a + 1u], o, inv, reach);
            if ta != MISS && tb != MISS {
                let b_first = tb < ta;
                if top < STACK {
                    stack_node[top] = select(a + 1u, a, b_first);
                    stack_enter[top] = max(ta, tb);
                    top++;
                } else {
                    // A deeper tree than the stack (refused on the host):
                    // never answer from a partial walk.
                    partial = true;
                }
                node = select(a, a + 1u, b_first);
                continue;
            } else if ta != MISS {
                node = a;
                continue;
            } else if tb != MISS {
                node = a + 1u;
                continue;
            }
        }
        // The next node on the stack still in reach.
        var next = NONE;
        while top > 0u {
            top--;
            if stack_enter[top] <= reach * EXIT_WIDEN {
                next = stack_node[top];
                break;
            }
        }
        if next == NONE {
            break;
        }
        node = next;
    }
    if tied || partial {
        found.sure = false;
    }
    return found;
}

// Ray i traced (a blocked ray: no candidate, the host answers it).
fn trace(i: u32, any: bool) -> Found {
    let ray = rays[i];
    if ray.origin.w < 0.0 {
        return Found(0.0, NONE, true);
    }
    return traverse(ray, any);
}

// Occlusion answers, two bits a ray, sixteen rays a word.
var<workgroup> words: array<atomic<u32>, 4>;

@compute @workgroup_size(64)
fn occluded(@builtin(global_invocation_id) id: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    if local < 4u {
        atomicStore(&words[local], 0u);
    }
    workgroupBarrier();
    if id.x < params.count {
        let found = trace(id.x, true);
        var code = ANSWER_MISS;
        if !found.sure {
            code = ANSWER_UNSURE;
        } else if found.tri != NONE {
            code = ANSWER_HIT;
        }
        atomicOr(&words[local / 16u], code << (2u * (local % 16u)));
    }
    workgroupBarrier();
    let word = id.x / 16u;
    if local % 16u == 0u && 16u * word < params.count {
        answers[word] = atomicLoad(&words[local / 16u]);
    }
}

@compute @workgroup_size(64)
fn closest(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i < params.count {
        let found = trace(i, false);
        answers[i] = select(found.tri | UNSURE_BIT, found.tri, found.sure || found.tri == NONE);
    }
}
