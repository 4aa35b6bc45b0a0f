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
shared uvec4 wg_subgroup_sums4[WG_THREADS];

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

uvec4 wg_exclusive_add4(uvec4 x) {
    uvec4 within = subgroupExclusiveAdd(x);
    uvec4 total = subgroupAdd(x);
    if (subgroupElect()) {
        wg_subgroup_sums4[gl_SubgroupID] = total;
    }
    barrier();
    if (gl_SubgroupID == 0) {
        uvec4 carry = uvec4(0);
        for (uint first = 0; first < gl_NumSubgroups; first += gl_SubgroupSize) {
            uint i = first + gl_SubgroupInvocationID;
            uvec4 s = i < gl_NumSubgroups ? wg_subgroup_sums4[i] : uvec4(0);
            uvec4 e = subgroupExclusiveAdd(s);
            if (i < gl_NumSubgroups) {
                wg_subgroup_sums4[i] = e + carry;
            }
            carry += subgroupAdd(s);
        }
    }
    barrier();
    uvec4 result = within + wg_subgroup_sums4[gl_SubgroupID];
    barrier();
    return result;
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
shared uvec4 wg_scan4[WG_THREADS];
shared uvec4 wg_segment_sums4[WG_SEGMENTS];

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

uvec4 wg_exclusive_add4(uvec4 x) {
    uint t = gl_LocalInvocationIndex;
    wg_scan4[t] = x;
    barrier();
    if (t < WG_SEGMENTS) {
        uvec4 sum = uvec4(0);
        for (uint j = t * WG_SEGMENT; j < (t + 1) * WG_SEGMENT; ++j) {
            uvec4 v = wg_scan4[j];
            wg_scan4[j] = sum;
            sum += v;
        }
        wg_segment_sums4[t] = sum;
    }
    barrier();
    if (t == 0) {
        uvec4 sum = uvec4(0);
        for (uint j = 0; j < WG_SEGMENTS; ++j) {
            uvec4 v = wg_segment_sums4[j];
            wg_segment_sums4[j] = sum;
            sum += v;
        }
    }
    barrier();
    uvec4 result = wg_scan4[t] + wg_segment_sums4[t / WG_SEGMENT];
    barrier();
    return result;
}

#endif
