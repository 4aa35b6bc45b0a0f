// pvssm's shared parts: the push block, the counters and the kernel math of Predicted Virtual
// Soft Shadow Maps (Shen et al. 2011): the light kernel s_alpha (Eq. 1), the pixel footprint
// phi' and their Gaussian convolution by a 2x2 Cholesky factorisation (Eq. 3 and Appendix), the
// perceptual metric rho(n) and the predicted texel size (Eqs. 4-5), and the exact coverage
// filter of the sheared kernel (Eq. 2, panel approximation of §4.2). 2-D quantities are in
// level-0 texels of the virtual map; kernel axes are half-axes. CPU twin: src/cpu/pvssm.rs.

#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "soft_light.glsl"
#include "small_int.glsl"
#include "dealt_tile.glsl"

// The pixel of this invocation in an 8 x 8 workgroup, laid out so that each run of eight
// invocations (a SIMD group of lavapipe's, subgroup size 8) covers a 4 x 2 block instead of a
// row of 8: a block crosses fewer shadow boundaries, so fewer groups pay a penumbra lane's
// search and filter for lanes that needed neither. Interleaved A/Bs on 2026-12-03 (medians of
// five to seven, the VM in a slow phase): teapot-rect's shape pass 66.0 -> 59.8 and 69.5 ->
// 65.4 ms, its filter 35.6 -> 36.7 and 40.2 -> 37.2; bunny-rect's shape 48.8 -> 45.7, filter
// 31.1 -> 30.0 — a few per cent, within the noise of single runs. The workgroup's tile is dealt
// (dealt_tile.glsl).
ivec2 simd_block_pixel() {
    uint l = gl_LocalInvocationIndex;
    uint lane = l & 7u;
    uint group = l >> 3u;
    uvec2 local = uvec2((group & 1u) * 4u + (lane & 3u), (group >> 1u) * 2u + (lane >> 2u));
    return ivec2(dealt_tile() * 8u + local);
}

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    uint virtual_size;
    uint page_size;
    uint levels;
    uint atlas_cols;
    // Texels per side of the conservative low-resolution map.
    uint lowres_size;
    // OPT_* bits, and the search's cells per side in bits 8..15.
    uint options;
    // soft_light.glsl's footprint factor for a map of virtual_size texels.
    vec2 light_size;
    float near;
    float far;
    int perspective;
    // Multiplies rho: more texels across each kernel (finer pages) above 1.
    float rho_scale;
    // Widest blocker-search region, low-resolution texels.
    float max_search;
    // How much nearer than the receiver's plane a low-resolution texel must be to block (NDC).
    float search_bias;
} pc;

#define OPT_ANTIALIAS 1u
#define OPT_RHO_STATIC 2u
#define OPT_REFINE_SHIFT 16u
#define OPT_ANCESTORS 4u
// The coarse early-out before the blocker search (`skip`).
#define OPT_COARSE_SKIP 8u
// blocker_depth = silhouette: the refined search averages the silhouette cells (shape.comp).
#define OPT_SILHOUETTE 16u
// kernel_proof: a sample whose kernel's reach holds no blocker in the conservative map is
// decided lit in the shape pass (shape.comp).
#define OPT_KERNEL_PROOF 32u
// kernel_proof = 2: that proof tried first, before the refined search, over its region and the
// reach together (shape.comp: the same decisions, without the refined search where it holds).
#define OPT_KERNEL_PROOF_FIRST (1u << 29u)
// Of the predicted z_avg's distance to the receiver, the least a silhouette cell's may have
// (0.1-0.5 measured: penumbra MAE teapot-rect 0.0152-0.0159, bunny-rect 0.0295-0.0307).
#define SILHOUETTE_GAP 0.25
// The host cleared the visibility image to 1 before the shape pass (it can where the image takes
// transfers: the engine's own does, a caller's may not): a sample decided lit stores nothing.
#define OPT_LIT_CLEARED 64u
// blocker_distance = centre: a blocking cell's distance from the centre-depth map (shape.comp's
// lowres_centre), else from the conservative map's minimum.
#define OPT_CENTRE_DISTANCE 128u
// Bits 20..23: fixed_level + 1 (0: the predicted level).
#define OPT_FIXED_SHIFT 20u
// lit_flag = conservative: a sample the blocker search finds unblocked is decided lit only where
// no cell of its region lies nearer than the receiver plane's *highest* depth over the cell
// (may_have_blocker: what the filter's per-texel test could find), not its lowest (shape.comp).
#define OPT_LIT_CONSERVATIVE (1u << 24u)
// Bits 25..28: log2(max_anisotropy) + 1, or 0 for no cap (predicted_level).
#define OPT_ANISO_SHIFT 25u
// Bits 8..15: the blocker search's cells per side (the push block has no room left).
#define OPT_CELLS_SHIFT 8u

#include "virtual_map.glsl"

// Counter slots, shared by the shape and filter passes. A sample the shape pass decides counts
// once, in its own class (C_OUTSIDE, C_FULLY_LIT, C_KERNEL_LIT), and the filter's in C_LIT,
// C_UMBRA or C_PENUMBRA; the host adds up the view samples and the lit (pvssm.rs's counters):
// an atomic is a walk over the SIMD lanes on lavapipe, and most samples are decided lit.
#define C_SAMPLES 0
#define C_OUTSIDE 1
#define C_LIT 2
#define C_UMBRA 3
#define C_PENUMBRA 4
#define C_FULLY_LIT 5
#define C_SEARCH_CLAMPED 6
#define C_REQUESTED 7
#define C_FALLBACK 8
#define C_FILTER_TEXELS 9
// Kernels wider than the filter's loop bound (MAX_SPAN texels a side at their level), cut.
#define C_FILTER_CUT 10
// Samples the coarse look (`skip`) decided lit without the full blocker search.
#define C_SKIPPED_LIT 11
// Samples the kernel's own reach proved lit after the refined search (`kernel_proof`).
#define C_KERNEL_LIT 12
// Of those, the ones proved before it (`kernel_proof = 2`): counted in C_KERNEL_LIT too.
#define C_KERNEL_LIT_FIRST 13
// The carries of C_FILTER_TEXELS past 2^32 (filter.comp adds them; the host joins the two words):
// a huge light at a large view reads more texels than a uint holds (bunny-rect at light x 100
// wrapped it before the strided levels).
#define C_FILTER_TEXELS_HIGH 14
#define COUNTERS 15

// Smallest kernel half-axis, level-0 texels: a point light without anti-aliasing still filters
// a finite box.
const float MIN_HALF = 1.0 / 64.0;

// The Appendix's convolution of two parallelograms (half-axes u0, v0 and u1, v1) as Gaussians:
// the summed variance V_h = L L^T, whose Cholesky columns are the result's half-axes, v_h
// vertical. The last square root is clamped (det(V_h) / m00 >= 0 in exact arithmetic).
void convolve(vec2 u0, vec2 v0, vec2 u1, vec2 v1, out vec2 u_h, out vec2 v_h) {
    float m00 = u0.x * u0.x + v0.x * v0.x + u1.x * u1.x + v1.x * v1.x;
    float m10 = u0.x * u0.y + v0.x * v0.y + u1.x * u1.y + v1.x * v1.y;
    float m11 = u0.y * u0.y + v0.y * v0.y + u1.y * u1.y + v1.y * v1.y;
    float a = sqrt(m00);
    u_h = a > 0.0 ? vec2(a, m10 / a) : vec2(0.0);
    v_h = vec2(0.0, sqrt(max(m11 - u_h.y * u_h.y, 0.0)));
}

// The perceptual metric (§5.1): the fewest texels a kernel n pixels wide must span, the user
// study's cubic in log2 n, with log2 n clamped to [0, the cubic's peak] (it turns over beyond).
float rho(float n) {
    bool fixed_scene = (pc.options & OPT_RHO_STATIC) != 0u;
    float x = clamp(log2(max(n, 1.0)), 0.0, fixed_scene ? 7.6 : 10.6);
    if (isnan(x)) {
        x = fixed_scene ? 7.6 : 10.6;
    }
    return fixed_scene ? 0.5477 + x * (1.406 + x * (-0.04687 + x * -0.003944))
                       : 0.667 + x * (0.7794 + x * (0.3967 + x * -0.02716));
}

// Eq. 4: the kernel's full widths along the map's axes, in pixels, through the pixel footprint
// F = [2 u_phi, 2 v_phi] — n0 = |F^-1 (2 u_h.x, 0)|, n1 = |F^-1 (0, 2 v_h.y)| — and, for the
// anisotropy cap, the screen length of the kernel's first column, n_u = |F^-1 (2 u_h)| (the
// second column is (0, 2 v_h.y): n1); +inf where the footprint is undefined or singular.
vec3 screen_sizes(bool has_pixel, vec2 u_phi, vec2 v_phi, vec2 u_h, vec2 v_h) {
    const float INF = 1.0 / 0.0;
    vec2 f0 = 2.0 * u_phi;
    vec2 f1 = 2.0 * v_phi;
    float det = f0.x * f1.y - f1.x * f0.y;
    float norm2 = dot(f0, f0) + dot(f1, f1);
    if (!has_pixel || !(abs(det) >= 1e-12 * (norm2 + 1e-30))) {
        return vec3(INF);
    }
    // F^-1 = [[f1.y, -f1.x], [-f0.y, f0.x]] / det, applied to (W0, 0) and (0, W1).
    float w0 = 2.0 * u_h.x;
    float w1 = 2.0 * v_h.y;
    vec2 n0 = vec2(f1.y, -f0.y) * (w0 / det);
    vec2 n1 = vec2(-f1.x, f0.x) * (w1 / det);
    vec2 n_u = n0 + vec2(-f1.x, f0.x) * (2.0 * u_h.y / det);
    return vec3(length(n0), length(n1), length(n_u));
}

// The coarsest level a kernel may be filtered at: the root (one page of page_size^2 texels over
// the whole map) at a stride of page_size / 2, 2 x 2 texels (predicted_level; root_strides.comp
// holds the levels between, each an even number of texels a side, as the filter's walk needs).
uint last_strided_level() {
    return pc.levels - 2u + page_shift(pc.page_size);
}

// Eq. 5 and the level whose texels are no larger than the required size — no smaller than the
// anisotropy cap's floor either (`max_anisotropy`, options bits OPT_ANISO_SHIFT): the larger of
// the kernel's two columns' own required sizes (|2 u_h| through n_u, 2 v_h.y through n1) over
// the cap. Why: Eq. 5 sizes texels by the kernel's thinner width, and where the pixel's
// footprint on a grazing receiver makes the kernel a needle (teapot-rect's terminator: 38 x 1
// level-0 texels) that asked for the finest pages along the whole terminator for a few samples
// each. As a texture's anisotropic filter does, the cap keeps texels no smaller than a
// max_anisotropy-th of the size the long axis asks for: across a thinner axis they are wider
// than it, which blurs it (twin: cpu::pvssm::anisotropy_cap).
//
// The level may lie past the root (pc.levels - 1), by up to log2(page_size) - 1: a *strided*
// level, which no page holds — the filter reads one root texel per 2^k x 2^k block there
// (root_strides.comp), so a kernel wider than the root's ~rho texels still reads ~rho^2 of them.
// Pages are asked for at min(level, root) (shape.comp).
uint predicted_level(vec2 u_h, vec2 v_h, vec3 n) {
    float r0 = 2.0 * u_h.x / (pc.rho_scale * rho(n.x));
    float r1 = 2.0 * v_h.y / (pc.rho_scale * rho(n.y));
    float r = min(r0, r1);
    uint cap = (pc.options >> OPT_ANISO_SHIFT) & 0xfu;
    if (cap != 0u) {
        float r_u = 2.0 * length(u_h) / (pc.rho_scale * rho(n.z));
        r = max(r, max(r_u, r1) / float(1u << (cap - 1u)));
    }
    if (!(r > 1.0)) {
        return 0u;
    }
    return min(uint(small_int(log2(r))), last_strided_level());
}

// The kernel's bounding box at `level`, in that level's texels: (lo, hi) inclusive.
ivec4 kernel_texels(vec2 c, vec2 u_h, vec2 v_h, uint level) {
    float s = float(1u << level);
    vec2 half_ext = vec2(u_h.x, abs(u_h.y) + v_h.y) / s;
    vec2 centre = c / s;
    return ivec4(floor_int(centre - half_ext), -floor_int(-(centre + half_ext)) - 1);
}

// The kernel's texels over the level's columns x_first..x_last: the parallelogram's rows there
// (its centre line's extremes over those columns, plus v_h), with a row of margin each side for
// the filter's per-column rounding. (lo, hi) inclusive, in level texels; lo.x > hi.x where the
// kernel misses the columns. A needle across the map's axes touches a thin band of its box.
ivec4 kernel_band(vec2 c, vec2 u_h, vec2 v_h, uint level, int x_first, int x_last) {
    float s = float(1u << level);
    vec2 centre = c / s;
    vec2 u = u_h / s;
    float vy = v_h.y / s;
    float xa = max(centre.x - u.x, float(x_first));
    float xb = min(centre.x + u.x, float(x_last + 1));
    if (!(xa < xb)) {
        return ivec4(1, 1, 0, 0);
    }
    float slope = u.y / u.x;
    float ya = centre.y + (xa - centre.x) * slope;
    float yb = centre.y + (xb - centre.x) * slope;
    return ivec4(floor_int(xa), floor_int(min(ya, yb) - vy) - 1,
                 -floor_int(-xb) - 1, -floor_int(-(max(ya, yb) + vy)));
}

// The page columns of `level` the kernel's box may reach (a texel of margin each side), clamped
// to the level: (first, last).
ivec2 kernel_page_columns(vec2 c, vec2 u_h, vec2 v_h, uint level) {
    ivec4 box = kernel_texels(c, u_h, v_h, level);
    int shift = int(page_shift(pc.page_size));
    int n_side = int(pages_per_side(pc.virtual_size, pc.page_size, level));
    return ivec2(max((box.x - 1) >> shift, 0), min((box.z + 1) >> shift, n_side - 1));
}

// The kernel's part in page column px of `level`: kernel_band's texels there, clipped to the
// column and to the level (texels off it are read as lit, from no page). (lo, hi) inclusive, in
// level texels; lo > hi in some component where the kernel has none there. The shape pass asks
// for the pages of these parts and the filter checks them, page column by page column.
ivec4 kernel_column_part(vec2 c, vec2 u_h, vec2 v_h, uint level, int px) {
    int ps = int(pc.page_size);
    int size = int(pc.virtual_size >> level);
    ivec4 band = kernel_band(c, u_h, v_h, level, px * ps - 1, px * ps + ps);
    return ivec4(max(band.xy, ivec2(px * ps, 0)), min(band.zw, ivec2(px * ps + ps - 1, size - 1)));
}
