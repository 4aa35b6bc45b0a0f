// Workgroup-wide exclusive sums of one value per invocation, in gl_LocalInvocationIndex order.
// Included by the scan and sort kernels. The includer defines WG_THREADS (the 1-D local size, a
// multiple of 8) and SUBGROUP_SCAN (1: subgroup arithmetic, which the device must support in
// compute shaders; 0: a shared-memory raking scan that runs anywhere). Call them in uniform
// control flow (they contain barriers). Arithmetic is modular (u32 wrap-around).
//
// The subgroup variant assumes that invocations are split into subgroups in local-index order
// (subgroup s holds indices s*gl_SubgroupSize ...): what every driver does for 1-D workgroups.
// The CPU twin (src/cpu/scan.rs) and the tests on both variants catch a driver that does not.

#if SUBGROUP_SCAN
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require

// One total per subgroup; gl_NumSubgroups <= WG_THREADS whatever the subgroup size.
shared uint wg_subgroup_sums[WG_THREADS];

uint wg_exclusive_add(uint x) {
    uint within = subgroupExclusiveAdd(x);
    uint total = subgroupAdd(x);
    if (subgroupElect()) {
        wg_subgroup_sums[gl_SubgroupID] = total;
    }
    barrier();
    // Subgroup 0 scans the subgroup totals, gl_SubgroupSize at a time: a loop, because small
    // subgroups give more totals than lanes (64 invocations in subgroups of 4: 16 totals).
    if (gl_SubgroupID == 0) {
        uint carry = 0;
        for (uint first = 0; first < gl_NumSubgroups; first += gl_SubgroupSize) {
            uint i = first + gl_SubgroupInvocationID;
            uint s = i < gl_NumSubgroups ? wg_subgroup_sums[i] : 0u;
            uint e = subgroupExclusiveAdd(s);
            if (i < gl_NumSubgroups) {
                wg_subgroup_sums[i] = e + carry;
            }
            carry += subgroupAdd(s);
        }
    }
    barrier();
    uint result = within + wg_subgroup_sums[gl_SubgroupID];
    // The next call writes the totals again: everyone must have read its result first.
    barrier();
    return result;
}



// Exclusive sums of two uvec4s per invocation at once, with one barrier: each subgroup posts its
// totals, then every invocation adds up the totals of the subgroups before its own (fewer than
// WG_THREADS / gl_SubgroupSize: 7 at most on lavapipe's 8 lanes, 1 on a 32-wide GPU). On lavapipe
// every barrier switches all of the workgroup's SIMD rows, and two separate scans of a uvec4 cost
// six: more than half of the sort histogram's time. Call it at most once per invocation (the
// totals are not guarded against a second call).
shared uvec4 wg_pair_sums[2 * WG_THREADS];

void wg_exclusive_add4x2(inout uvec4 a, inout uvec4 b) {
    uvec4 before_a = subgroupExclusiveAdd(a);
    uvec4 before_b = subgroupExclusiveAdd(b);
    uvec4 total_a = subgroupAdd(a);
    uvec4 total_b = subgroupAdd(b);
    if (subgroupElect()) {
        wg_pair_sums[2 * gl_SubgroupID] = total_a;
        wg_pair_sums[2 * gl_SubgroupID + 1] = total_b;
    }
    barrier();
    for (uint s = 0; s < gl_SubgroupID; ++s) {
        before_a += wg_pair_sums[2 * s];
        before_b += wg_pair_sums[2 * s + 1];
    }
    a = before_a;
    b = before_b;
}

#else

// Raking: the WG_THREADS values are cut into segments of WG_SEGMENT; one invocation per segment
// scans it serially, one invocation scans the segment totals, and everyone adds its segment's
// offset. Four barriers, where a Hillis-Steele scan of 64 values needs seven; on lavapipe each
// barrier switches every SIMD row of the workgroup, so barriers dominate such small scans.
#define WG_SEGMENT 8
#define WG_SEGMENTS (WG_THREADS / WG_SEGMENT)

shared uint wg_scan[WG_THREADS];
shared uint wg_segment_sums[WG_SEGMENTS];

uint wg_exclusive_add(uint x) {
    uint t = gl_LocalInvocationIndex;
    wg_scan[t] = x;
    barrier();
    if (t < WG_SEGMENTS) {
        uint sum = 0;
        for (uint j = t * WG_SEGMENT; j < (t + 1) * WG_SEGMENT; ++j) {
            uint v = wg_scan[j];
            wg_scan[j] = sum;
            sum += v;
        }
        wg_segment_sums[t] = sum;
    }
    barrier();
    if (t == 0) {
        uint sum = 0;
        for (uint j = 0; j < WG_SEGMENTS; ++j) {
            uint v = wg_segment_sums[j];
            wg_segment_sums[j] = sum;
            sum += v;
        }
    }
    barrier();
    uint result = wg_scan[t] + wg_segment_sums[t / WG_SEGMENT];
    // The next call writes the same arrays: everyone must have read its result first.
    barrier();
    return result;
}



// wg_exclusive_add4x2 without subgroup operations: both raking scans in one round of barriers.
shared uvec4 wg_pair_scan[2 * WG_THREADS];
shared uvec4 wg_pair_segments[2 * WG_SEGMENTS];

void wg_exclusive_add4x2(inout uvec4 a, inout uvec4 b) {
    uint t = gl_LocalInvocationIndex;
    wg_pair_scan[t] = a;
    wg_pair_scan[WG_THREADS + t] = b;
    barrier();
    if (t < 2 * WG_SEGMENTS) {
        uint first = (t % WG_SEGMENTS) * WG_SEGMENT + (t / WG_SEGMENTS) * WG_THREADS;
        uvec4 sum = uvec4(0);
        for (uint j = first; j < first + WG_SEGMENT; ++j) {
            uvec4 v = wg_pair_scan[j];
            wg_pair_scan[j] = sum;
            sum += v;
        }
        wg_pair_segments[t] = sum;
    }
    barrier();
    if (t < 2) {
        uvec4 sum = uvec4(0);
        for (uint j = t * WG_SEGMENTS; j < (t + 1) * WG_SEGMENTS; ++j) {
            uvec4 v = wg_pair_segments[j];
            wg_pair_segments[j] = sum;
            sum += v;
        }
    }
    barrier();
    a = wg_pair_scan[t] + wg_pair_segments[t / WG_SEGMENT];
    b = wg_pair_scan[WG_THREADS + t] + wg_pair_segments[WG_SEGMENTS + t / WG_SEGMENT];
}

#endif
