// Rays on the GPU: one invocation per ray, a stack traversal of a BVH2
// (obvhs's, flattened by flatten.rs), the nearer child first. Two entry
// points: `occluded` (any hit ends the ray) and `closest` (the closest hit,
// cut at the ray's cap).
//
// In: nodes (box, then first child or first triangle, and the leaf's
// triangle count: 0 for an inner node, whose children are adjacent),
// triangles in leaf order (obvhs's RtTriangle), rays as the CPU traces
// them (origin already shifted back by SHIFT, the end t_max + SHIFT, unit
// direction, and for `closest` the cap: where a hit beyond is taken as a
// hit at it, Hit::cap in bvh.rs). A ray whose end is negative is blocked.
// Out, per ray i: `occluded` writes answers[i] = 1 if a triangle (either
// face) is hit at t in [SHIFT, end], else 0 (blocked: 1); `closest` writes
// answers[3i] = the hit's t (bits), answers[3i + 1] = its triangle in leaf
// order, NONE for no hit (blocked: none), and answers[3i + 2] another
// triangle hit at exactly that t below the cap, else NONE: a tie, which
// the CPU breaks by its own traversal order, so the host asks the CPU.
//
// The triangle test is the CPU backend's (obvhs's RtTriangle::intersect,
// both faces, on the triangle's precomputed edges and normal), on the ray
// the CPU traces: started SHIFT behind its origin with t in [SHIFT,
// t_max + SHIFT] (see BOX_EPSILON_SHIFT in bvh.rs; the host shifts it, so
// its rounding is the CPU's). A receiver's origin can lie on another
// surface's plane within rounding (a texel on the edge between a wall and
// the floor): there the answer is decided by rounding, and the same
// operations on the same values decide it as the CPU does. The closest
// hit keeps obvhs's rule: a hit replaces the best only when strictly
// nearer, the triangle test bounded by the best so far. The box test
// widens each box's exit by 2 gamma_3 (Ize 2013, "Robust BVH Ray
// Traversal") so rounding never culls a box the ray enters.

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

const STACK: u32 = 64u;
// 1 + 2 gamma_3, gamma_n = n eps / (1 - n eps), eps = 2^-24.
const EXIT_WIDEN: f32 = 1.0000004;
// The CPU backend's shift (BOX_EPSILON_SHIFT in bvh.rs).
const SHIFT: f32 = 2e-4;
const NONE: u32 = 0xffffffffu;
const MISS: f32 = -1.0;

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    // In the CPU's order: (x + y) + z.
    return (a.x * b.x + a.y * b.y) + a.z * b.z;
}

// The t in [t_min, t_max] where the triangle is hit (either face), else
// MISS: obvhs's RtTriangle::intersect.
fn hit_triangle(tri: Tri, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> f32 {
    let c = tri.v0.xyz - o;
    // d x c as glam computes it.
    let r = vec3<f32>(d.y * c.z - c.y * d.z, d.z * c.x - c.z * d.x, d.x * c.y - c.x * d.y);
    let inv_det = 1.0 / dot3(tri.ng.xyz, d);
    let u = dot3(r, tri.e2.xyz) * inv_det;
    let v = dot3(r, tri.e1.xyz) * inv_det;
    let w = 1.0 - u - v;
    // u, v, w >= 0 with their sign bits (a -0.0 fails, as on the CPU).
    let signs = bitcast<u32>(u) | bitcast<u32>(v) | bitcast<u32>(w);
    if inv_det == 0.0 || (signs & 0x80000000u) != 0u {
        return MISS;
    }
    let t = dot3(tri.ng.xyz, c) * inv_det;
    if t >= t_min && t <= t_max {
        return t;
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
    // Another triangle hit at exactly t (below the cap), else NONE.
    tie: u32,
};

// The traversal both entry points share: with `any`, the first hit found
// (t unused); else the closest, each hit's t capped at `cap`.
fn traverse(ray: Ray, any: bool) -> Found {
    var found = Found(ray.origin.w, NONE, NONE);
    let d = ray.dir.xyz;
    let o = ray.origin.xyz;
    let cap = ray.dir.w;
    // Zero components get a tiny stand-in: finite slabs, same side.
    let tiny = vec3<f32>(1e-20);
    let safe = select(d, select(tiny, -tiny, d < vec3<f32>(0.0)), abs(d) < tiny);
    let inv = 1.0 / safe;
    if enter_box(nodes[0], o, inv, found.t) == MISS {
        return found;
    }
    // Nodes to visit with where the ray enters them: a node entered
    // beyond the closest hit found since is skipped.
    var stack_node: array<u32, STACK>;
    var stack_enter: array<f32, STACK>;
    var top = 0u;
    var node = 0u;
    loop {
        let n = nodes[node];
        if n.count > 0u {
            for (var k = n.first; k < n.first + n.count; k++) {
                var t = hit_triangle(tris[k], o, d, SHIFT, found.t);
                if t == MISS {
                    continue;
                }
                if any {
                    found.tri = k;
                    return found;
                }
                t = min(t, cap);
                if t < found.t {
                    found = Found(t, k, NONE);
                } else if t == found.t && t < cap && k != found.tri {
                    found.tie = k;
                }
            }
        } else {
            let a = n.first;
            let ta = enter_box(nodes[a], o, inv, found.t);
            let tb = enter_box(nodes[a + 1u], o, inv, found.t);
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
            if stack_enter[top] <= found.t * EXIT_WIDEN {
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

@compute @workgroup_size(64)
fn occluded(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.count {
        return;
    }
    let ray = rays[i];
    if ray.origin.w < 0.0 {
        answers[i] = 1u;
        return;
    }
    answers[i] = select(0u, 1u, traverse(ray, true).tri != NONE);
}

@compute @workgroup_size(64)
fn closest(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.count {
        return;
    }
    let ray = rays[i];
    var found = Found(0.0, NONE, NONE);
    if ray.origin.w >= 0.0 {
        found = traverse(ray, false);
    }
    answers[3u * i] = bitcast<u32>(found.t);
    answers[3u * i + 1u] = found.tri;
    answers[3u * i + 2u] = found.tie;
}
