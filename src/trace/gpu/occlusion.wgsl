// Occlusion rays on the GPU: one invocation per ray, a stack traversal of
// a BVH2 (obvhs's, flattened by flatten.rs), any hit ends it.
//
// In: nodes (box, then first child or first triangle, and the leaf's
// triangle count: 0 for an inner node, whose children are adjacent),
// triangles in leaf order (three vertices), rays (origin and t_max, unit
// direction). Out: per ray 1 if a triangle (either face) is hit at a
// distance in (0, t_max], else 0; a ray with t_max < 0 is blocked (1,
// untraced).
//
// The triangle test is watertight (Woop, Benthin and Wald 2013, "Watertight
// Ray/Triangle Intersection"): a ray through a shared edge or vertex hits
// one of the triangles around it, never slips between them. The box test
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
    v1: vec4<f32>,
    v2: vec4<f32>,
};

struct Ray {
    origin: vec4<f32>, // xyz, w: t_max
    dir: vec4<f32>,    // xyz unit, w unused
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

fn component(v: vec3<f32>, k: u32) -> f32 {
    if k == 0u {
        return v.x;
    }
    if k == 1u {
        return v.y;
    }
    return v.z;
}

// Whether the triangle is hit at t in (0, t_max], both faces.
fn hit_triangle(
    tri: Tri, o: vec3<f32>, kx: u32, ky: u32, kz: u32, s: vec3<f32>, t_max: f32,
) -> bool {
    let a = tri.v0.xyz - o;
    let b = tri.v1.xyz - o;
    let c = tri.v2.xyz - o;
    let az = component(a, kz);
    let bz = component(b, kz);
    let cz = component(c, kz);
    let ax = component(a, kx) - s.x * az;
    let ay = component(a, ky) - s.y * az;
    let bx = component(b, kx) - s.x * bz;
    let by = component(b, ky) - s.y * bz;
    let cx = component(c, kx) - s.x * cz;
    let cy = component(c, ky) - s.y * cz;
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return false;
    }
    let det = u + v + w;
    if det == 0.0 {
        return false;
    }
    let t_scaled = u * s.z * az + v * s.z * bz + w * s.z * cz;
    // Both faces: compare with det's sign taken out.
    let sgn = select(1.0, -1.0, det < 0.0);
    let t = t_scaled * sgn;
    let d = det * sgn;
    return t > 0.0 && t <= t_max * d;
}

@compute @workgroup_size(64)
fn occluded(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.count {
        return;
    }
    let ray = rays[i];
    let t_max = ray.origin.w;
    if t_max < 0.0 {
        hits[i] = 1u;
        return;
    }
    let o = ray.origin.xyz;
    let d = ray.dir.xyz;
    // The watertight test's frame: z along the direction's largest
    // component, x and y swapped to keep the winding.
    let ad = abs(d);
    var kz = 2u;
    if ad.x > ad.y && ad.x > ad.z {
        kz = 0u;
    } else if ad.y > ad.z {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    let dz = component(d, kz);
    if dz < 0.0 {
        let k = kx;
        kx = ky;
        ky = k;
    }
    let s = vec3<f32>(component(d, kx) / dz, component(d, ky) / dz, 1.0 / dz);
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
        let leave = min(min(far.x, far.y), min(far.z, t_max)) * EXIT_WIDEN;
        if enter <= leave {
            if n.count > 0u {
                for (var k = 0u; k < n.count; k++) {
                    if hit_triangle(tris[n.first + k], o, kx, ky, kz, s, t_max) {
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
