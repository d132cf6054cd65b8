// Deferred Phong over the G-buffer (directional lights + ambient, Blinn half-vector specular
// 0.25·(n·h)^32), every shadow-casting light looked up in its own shadow map (one per light,
// as the CPU reference) with a normal offset, a slope-free bias of two texels plus the
// receiver's splat size, and PCF. Writes sRGB RGBA8 (rounded like the CPU reference);
// screen-space ambient occlusion scales the ambient term. Mirrors core::render's `shade`.
// #import common/types.wgsl

@group(0) @binding(0) var<uniform> view: View;
// One entry per shadow map drawn this frame (LightGpu::shadow_map indexes it).
@group(0) @binding(1) var<storage, read> shadow_maps: array<ShadowMap>;
@group(0) @binding(2) var<uniform> shading: Shading;
@group(0) @binding(3) var<storage, read> lights: array<LightGpu>;
@group(0) @binding(4) var<storage, read> gbuffer: array<vec4<u32>>;
// Every shadow map's keys, 32-bit layout, map m from shadow_maps[m].key_word_offset:
// [offset + 2p + 1] = depth bits of texel p.
@group(0) @binding(5) var<storage, read> shadow_keys: array<u32>;
@group(0) @binding(6) var output: texture_storage_2d<rgba8unorm, write>;
// KRS lighting inputs (krs_trace.wgsl `light`), `shading.krs_stride` entries per pixel:
// [0] = (shading point, KRS ambient accessibility, + 2 on KRS pixels), [1 + l] = (Algorithm 2 factor, 1 when it
// replaces n·l, visibility of light l through the KRS, 0).
@group(0) @binding(7) var<storage, read> krs_light: array<vec4<f32>>;

// Fraction of the light of shadow map `map` reaching p (the CPU's `ShadowMap::visibility`).
fn visibility(map: u32, p_world: vec3<f32>, n_world: vec3<f32>, receiver_world: f32) -> f32 {
    let shadow_view = shadow_maps[map].view;
    let key_base = shadow_maps[map].key_word_offset;
    let texel_world = 2.0 / shadow_view.fy;
    let offset = n_world * (1.5 * texel_world);
    let q = (shadow_view.view_from_world * vec4<f32>(p_world + offset, 1.0)).xyz;
    let s = project_view(shadow_view, q);
    let bias = 2.0 * texel_world + 1.5 * receiver_world;
    let recv = ndc_depth(shadow_view, s.z - bias);
    let w = i32(shadow_view.size.x);
    let h = i32(shadow_view.size.y);
    let ix = i32(floor(s.x));
    let iy = i32(floor(s.y));
    let r = i32(shading.pcf_radius);
    var lit = 0u;
    var taps = 0u;
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            let x = ix + dx;
            let y = iy + dy;
            taps++;
            if x < 0 || y < 0 || x >= w || y >= h {
                lit++;
                continue;
            }
            let bits = shadow_keys[key_base + 2u * u32(y * w + x) + 1u];
            if bits == EMPTY || recv <= bitcast<f32>(bits) {
                lit++;
            }
        }
    }
    return f32(lit) / f32(taps);
}

// core's `ao_pixel_jitter`: three values in [0, 1) from seeds 3·pixel + 1 ..= 3·pixel + 3.
fn ao_pixel_jitter(pixel: u32) -> vec3<f32> {
    let seed = pixel * 3u;
    return vec3<f32>(ao_jitter(seed + 1u), ao_jitter(seed + 2u), ao_jitter(seed + 3u));
}

// Screen-space ambient occlusion, the CPU's `AoKernel::openness` (docs/rendering.md "Ambient
// occlusion"): fraction of the samples around p (the kernel's phases plus the pixel's jitter)
// not occluded by a depth-buffer surface nearer the eye than the sample by more than eps_world
// and less than the radius.
fn ao_openness(p: vec3<f32>, n: vec3<f32>, pixel: u32, eps_world: f32) -> f32 {
    if shading.ao_count == 0u || all(n == vec3<f32>(0.0)) {
        return 1.0;
    }
    var helper = vec3<f32>(1.0, 0.0, 0.0);
    if abs(n.y) < 0.99 {
        helper = vec3<f32>(0.0, 1.0, 0.0);
    }
    let t = normalize_or_zero(cross(n, helper));
    let b = cross(n, t);
    let w = f32(view.size.x);
    let h = f32(view.size.y);
    var occluded = 0u;
    let count = f32(shading.ao_count);
    let jitter = ao_pixel_jitter(pixel);
    for (var i = 0u; i < shading.ao_count; i++) {
        // core's `ao_sample_offset`: the sample's phases plus this pixel's jitter.
        let phases = shading.ao_kernel[i].xyz;
        let u = min(phases.x + jitter.x / count, 1.0);
        let cos_t = sqrt(1.0 - u);
        let sin_t = sqrt(u);
        let phi = 6.2831855 * fract(phases.y + jitter.y);
        let dist = shading.ao_radius * (0.25 + 0.75 * fract(phases.z + jitter.z));
        let s = vec3<f32>(sin_t * cos(phi), sin_t * sin(phi), cos_t) * dist;
        let q = p + t * s.x + b * s.y + n * s.z;
        let qv = (view.view_from_world * vec4<f32>(q, 1.0)).xyz;
        let d_q = -qv.z;
        if view.perspective != 0u && d_q <= view.near {
            continue;
        }
        let sp = project_view(view, qv);
        if !(sp.x >= 0.0 && sp.y >= 0.0 && sp.x < w && sp.y < h) {
            continue;
        }
        let q_pixel = u32(sp.y) * view.size.x + u32(sp.x);
        let g = gbuffer[q_pixel];
        if g.w == EMPTY {
            continue;
        }
        // KRS surfaces occlude through the KRS distance AO instead (the CPU's `is_krs`).
        if shading.krs_stride > 0u && krs_light[q_pixel * shading.krs_stride].w >= 2.0 {
            continue;
        }
        let gap = d_q - view_depth_of(view, bitcast<f32>(g.w));
        if gap > eps_world && gap < shading.ao_radius {
            occluded++;
        }
    }
    return 1.0 - f32(occluded) / f32(shading.ao_count);
}

fn to_unorm8(c: f32) -> f32 {
    // The CPU writes round(srgb · 255) as u8; store exactly that value.
    return round(linear_to_srgb(c) * 255.0) / 255.0;
}

@compute @workgroup_size(8, 8)
fn shade(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= view.size.x || gid.y >= view.size.y {
        return;
    }
    let g = gbuffer[gid.y * view.size.x + gid.x];
    var c = shading.background.xyz;
    if g.w != EMPTY {
        let ab = unpack2x16unorm(g.x);
        let bz = unpack2x16unorm(g.y);
        let nxy = unpack2x16snorm(g.z);
        let albedo = vec3<f32>(ab, bz.x);
        let n = normalize_or_zero(vec3<f32>(nxy, bz.y * 2.0 - 1.0));
        let depth = bitcast<f32>(g.w);
        var p = unproject(view, vec2<f32>(gid.xy) + 0.5, depth);
        let ks = shading.krs_stride;
        let kbase = (gid.y * view.size.x + gid.x) * ks;
        var krs_open = 1.0;
        if ks > 0u {
            // A KRS pixel keeps its exact hit point (the same unprojection elsewhere).
            let e = krs_light[kbase];
            p = e.xyz;
            // KRS pixels carry their accessibility plus 2 (krs_trace.wgsl `light`).
            krs_open = select(e.w, e.w - 2.0, e.w >= 2.0);
        }
        let v = toward_eye(view, p);
        let receiver = pixel_world_size(view, view_depth_of(view, depth)) * shading.receiver_px;
        // The AO staircase tolerance: the receiver term of the shadow bias.
        let open = ao_openness(p, n, gid.y * view.size.x + gid.x, 1.5 * receiver);
        var light = shading.ambient.xyz * (open * krs_open);
        var spec = vec3<f32>(0.0);
        for (var i = 0u; i < shading.light_count; i++) {
            let l = lights[i].to_light;
            let color = lights[i].color.xyz;
            var ndotl = dot(n, l);
            var krs_vis = 1.0;
            if ks > 0u {
                // Algorithm 2 replaces n·l on KRS pixels; KRS shadow rays from every pixel.
                let e = krs_light[kbase + 1u + i];
                if e.y > 0.0 {
                    ndotl = e.x;
                }
                krs_vis = e.z;
            }
            if ndotl <= 0.0 {
                continue;
            }
            var vis = 1.0;
            let map = lights[i].shadow_map;
            if map != NO_SHADOW_MAP {
                vis = visibility(map, p, n, receiver);
            }
            vis *= krs_vis;
            if vis <= 0.0 {
                continue;
            }
            light += color * (ndotl * vis);
            let half_v = normalize_or_zero(l + v);
            spec += color * (0.25 * pow(max(dot(n, half_v), 0.0), 32.0) * vis);
        }
        c = albedo * light + spec;
    }
    textureStore(output, vec2<i32>(gid.xy), vec4<f32>(to_unorm8(c.x), to_unorm8(c.y), to_unorm8(c.z), 1.0));
}
