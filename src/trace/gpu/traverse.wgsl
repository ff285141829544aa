// Rays on the GPU: one invocation per ray, a stack traversal of a BVH2
// (obvhs's, flattened by flatten.rs), the nearer child first. Two entry
// points: `occluded` (any candidate ends the ray) and `closest` (the
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
// Out: candidates, which the host settles with the CPU's own triangle
// test (gpu/mod.rs). The test here is the CPU's (obvhs's
// RtTriangle::intersect, both faces, on the same precomputed edges and
// normal, the same operations in the same order) with a margin: a
// triangle counts when its barycentrics are above -BARY_MARGIN and its t
// within T_MARGIN (relative) of the ray's range. A GPU may fuse a multiply
// and an add where the CPU rounds twice, and on a ray through an edge
// that decides the answer; with the margin every triangle the CPU hits is
// a candidate here too, and the host retests the one found.
// `occluded` writes answers[i] = a candidate, else NONE. `closest` writes
// answers[2i] = the nearest candidate triangle (its distance the host's
// retest gives), NONE for none, answers[2i + 1] = another occluder's
// triangle hit within WINDOW (relative) of it below the cap, else NONE: a
// near tie, which rounding or the CPU's traversal order decides, so the
// host asks the CPU.
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
// The triangle test's margins (see above): far beyond a fused
// multiply-add's rounding except at grazing angles, and thin enough that
// a candidate the CPU misses is rare.
const BARY_MARGIN: f32 = 1e-4;
const T_MARGIN: f32 = 1e-5;
// Two candidates nearer each other than this (relative) are a near tie.
const WINDOW: f32 = 1e-5;

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    // In the CPU's order: (x + y) + z.
    return (a.x * b.x + a.y * b.y) + a.z * b.z;
}

// The t where the triangle is a candidate (either face) in [t_min, t_max]
// widened by the margins, else MISS.
fn candidate(tri: Tri, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> f32 {
    let c = tri.v0.xyz - o;
    // d x c as glam computes it.
    let r = vec3<f32>(d.y * c.z - c.y * d.z, d.z * c.x - c.z * d.x, d.x * c.y - c.x * d.y);
    let det = dot3(tri.ng.xyz, d);
    if det == 0.0 {
        return MISS;
    }
    let inv_det = 1.0 / det;
    let u = dot3(r, tri.e2.xyz) * inv_det;
    let v = dot3(r, tri.e1.xyz) * inv_det;
    let w = 1.0 - u - v;
    if !(min(u, min(v, w)) >= -BARY_MARGIN) {
        return MISS;
    }
    let t = dot3(tri.ng.xyz, c) * inv_det;
    if t >= t_min * (1.0 - T_MARGIN) && t <= t_max * (1.0 + T_MARGIN) {
        return max(t, 0.0);
    }
    return MISS;
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
    // Another occluder's candidate within WINDOW of t (below the cap).
    tie: u32,
};

// Whether two candidates' t are a near tie.
fn near(a: f32, b: f32) -> bool {
    return abs(a - b) <= WINDOW * max(a, b);
}

// The traversal both entry points share: with `any`, the first candidate
// found (t unused); else the nearest, each candidate's t capped at `cap`.
fn traverse(ray: Ray, any: bool) -> Found {
    var found = Found(ray.origin.w, NONE, NONE);
    let d = ray.dir.xyz;
    let o = ray.origin.xyz;
    let cap = ray.dir.w;
    // Zero components get a tiny stand-in: finite slabs, same side.
    let tiny = vec3<f32>(1e-20);
    let safe = select(d, select(tiny, -tiny, d < vec3<f32>(0.0)), abs(d) < tiny);
    let inv = 1.0 / safe;
    // How far candidates are looked for: past the nearest so far by the
    // tie window (past the ray's end by the margin).
    var reach = found.t * (1.0 + WINDOW);
    if enter_box(nodes[0], o, inv, reach) == MISS {
        return found;
    }
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
                let hit = candidate(tris[k], o, d, SHIFT, reach);
                if hit == MISS {
                    continue;
                }
                if any {
                    found.tri = k;
                    return found;
                }
                let t = min(hit, cap);
                let other = found.tri != NONE && occluder[k] != occluder[found.tri];
                if found.tri == NONE || t < found.t {
                    // The one it replaces, if near, is a tie of the new.
                    let tied = other && found.t < cap && near(t, found.t);
                    found = Found(t, k, select(NONE, found.tri, tied));
                    reach = min(found.t * (1.0 + WINDOW), reach);
                } else if other && t < cap && near(t, found.t) {
                    found.tie = k;
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
    return found;
}

// Ray i traced (a blocked ray: no candidate, the host answers it).
fn trace(i: u32, any: bool) -> Found {
    let ray = rays[i];
    if ray.origin.w < 0.0 {
        return Found(0.0, NONE, NONE);
    }
    return traverse(ray, any);
}

@compute @workgroup_size(64)
fn occluded(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x < params.count {
        answers[id.x] = trace(id.x, true).tri;
    }
}

@compute @workgroup_size(64)
fn closest(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i < params.count {
        let found = trace(i, false);
        answers[2u * i] = found.tri;
        answers[2u * i + 1u] = found.tie;
    }
}
