// Occlusion rays on the GPU: one invocation per ray, a stack traversal of
// a BVH2 (obvhs's, flattened by flatten.rs), any hit ends it.
//
// In: nodes (box, then first child or first triangle, and the leaf's
// triangle count: 0 for an inner node, whose children are adjacent),
// triangles in leaf order (obvhs's RtTriangle), rays as the CPU traces
// them (origin already shifted back by SHIFT, the end t_max + SHIFT, unit
// direction). Out: per ray 1 if a triangle (either face) is hit at t in
// [SHIFT, end], else 0; a ray whose end is negative is blocked (1,
// untraced).
//
// The triangle test is the CPU backend's (obvhs's RtTriangle::intersect,
// both faces, on the triangle's precomputed edges and normal), on the ray
// the CPU traces: started SHIFT behind its origin with t in [SHIFT,
// t_max + SHIFT] (see BOX_EPSILON_SHIFT in bvh.rs; the host shifts it, so
// its rounding is the CPU's). A receiver's origin
// can lie on another surface's plane within rounding (a texel on the edge
// between a wall and the floor): there the answer is decided by rounding,
// and the same operations on the same values decide it as the CPU does.
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
    dir: vec4<f32>,    // xyz unit (no -0.0), w unused
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
@group(0) @binding(3) var<storage, read_write> hits: array<u32>;
@group(0) @binding(4) var<uniform> params: Params;

const STACK: u32 = 64u;
// 1 + 2 gamma_3, gamma_n = n eps / (1 - n eps), eps = 2^-24.
const EXIT_WIDEN: f32 = 1.0000004;

// The CPU backend's shift (BOX_EPSILON_SHIFT in bvh.rs).
const SHIFT: f32 = 2e-4;

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    // In the CPU's order: (x + y) + z.
    return (a.x * b.x + a.y * b.y) + a.z * b.z;
}

// Whether the triangle is hit at t in [t_min, t_max] (either face):
// obvhs's RtTriangle::intersect.
fn hit_triangle(tri: Tri, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> bool {
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
        return false;
    }
    let t = dot3(tri.ng.xyz, c) * inv_det;
    return t >= t_min && t <= t_max;
}

@compute @workgroup_size(64)
fn occluded(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.count {
        return;
    }
    let ray = rays[i];
    let t_end = ray.origin.w;
    if t_end < 0.0 {
        hits[i] = 1u;
        return;
    }
    let d = ray.dir.xyz;
    let o = ray.origin.xyz;
    let t_min = SHIFT;
    let ad = abs(d);
    // Zero components get a tiny stand-in: finite slabs, same side.
    let tiny = vec3<f32>(1e-20);
    let safe = select(d, select(tiny, -tiny, d < vec3<f32>(0.0)), ad < tiny);
    let inv = 1.0 / safe;

    var stack: array<u32, STACK>;
    var top = 0u;
    var node = 0u;
    loop {
        let n = nodes[node];
        let t0 = (n.lo - o) * inv;
        let t1 = (n.hi - o) * inv;
        let near = min(t0, t1);
        let far = max(t0, t1);
        let enter = max(max(near.x, near.y), max(near.z, 0.0));
        let leave = min(min(far.x, far.y), min(far.z, t_end)) * EXIT_WIDEN;
        if enter <= leave {
            if n.count > 0u {
                for (var k = 0u; k < n.count; k++) {
                    if hit_triangle(tris[n.first + k], o, d, t_min, t_end) {
                        hits[i] = 1u;
                        return;
                    }
                }
            } else if top < STACK {
                stack[top] = n.first + 1u;
                top++;
                node = n.first;
                continue;
            }
        }
        if top == 0u {
            break;
        }
        top--;
        node = stack[top];
    }
    hits[i] = 0u;
}
