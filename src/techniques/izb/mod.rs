//! `izb` and `izb-soft`: the irregular z-buffer (book §4.5, §7.4; Johnson et al. 2005, Sintorn
//! et al. 2008) — shadows evaluated exactly at the view samples, with no shadow-map resolution
//! and no depth bias, in compute (lavapipe has neither conservative rasterization nor fragment
//! interlock).
//!
//! **Passes** (`glsl/izb/`, one frame, no readback):
//! 1. `bin`: each view sample whose light is not entirely behind its tangent plane gets the
//!    reference's shadow-ray origin `o = p + δ·n` and is counted into the light-space grid cell
//!    its projection from the light centre falls in (its local index from the `atomicAdd`);
//!    each cell keeps its deepest sample. Samples no projection reaches (at or behind a
//!    perspective light's plane) go to one extra *overflow* cell.
//! 2. `bin-scan` and `bin-scatter`: the exclusive prefix sum of the counts, and a compacted list
//!    of view samples per cell (the book's count → scan → scatter).
//! 3. `footprint`: per triangle, the cells whose samples it may shadow (below), as
//!    (triangle, cell) pairs in per-cell triangle lists — counted per cell, scanned, and
//!    written at the cell's offset plus a cursor. A footprint whose cell range fits 8 × 8
//!    cells keeps, from the count, a 64-bit mask of the cells it reaches, and the write emits
//!    those instead of walking the range again (2026-12-05: footprint pass 7.45 → 6.55 ms
//!    minimum on bunny-rect for `izb`, 10.8 → 8.6 for `izb-soft`, 64 → 52 and 129 → 90 on
//!    `grid:1000000@rect`; pairs, lists and visibility the same). Footprints of more than 256 cells go to a
//!    second pass of 1024 workgroups: one workgroup a triangle up to 16 384 cells, and every
//!    workgroup a share of each larger one's (a full-screen triangle), so no loop outgrows
//!    lavapipe's loop limiter. Each cell's *work items* follow: chunks of [`ITEM_SAMPLES`]
//!    samples (times [`SOFT_SAMPLES_PER_INVOCATION`] for `izb-soft`'s batched test) times
//!    chunks of [`HARD_ITEM_TRIANGLES`] (`izb`) or [`soft_item_triangles`] (`izb-soft`)
//!    triangles, scanned, so no item's work grows with a grazing cell's lists.
//! 4. `test` (dispatched indirectly, one workgroup per item, found by a binary search of the
//!    items' prefix sum): an invocation per sample (`izb-soft`'s batched test: two, each
//!    batch of triangles set up once for both), the item's triangles in turn — the same for
//!    every invocation, read through texel views (`glsl/izb/item_triangles.glsl`), eight at a
//!    time where the device has subgroup shuffles (below) — each tested with the reference's
//!    watertight shadow-ray test
//!    (`glsl/include/watertight.glsl`, bit for bit the same arithmetic on the same origin and
//!    direction); the mask stays in registers and is written once.
//!
//! **Why samples across the SIMD lanes and triangles in the loop.** The first version ran one
//! invocation per (triangle, chunk of samples), each looping over its samples: every test then
//! read its sample and its mask with per-invocation addresses. On lavapipe (Mesa 22.3) such
//! reads run lane by lane, a storage buffer's reads are scalar only outside all control flow,
//! and both sides of a branch run for the whole SIMD group under a mask; with the samples in the
//! lanes, the triangle is the same for all of them (a texel-buffer gather), the parameters are a
//! uniform block (scalar reads anywhere), the sample's data and mask are read once per item, and
//! the rare, costly branches of the soft test were loops of at most one pass (`WHEN`,
//! `glsl/include/when.glsl`), which that lavapipe skipped when no lane entered (Mesa 25 skips an
//! `if` too, and the soft test now uses `if`s: **Branches** below). Measured on `teapot-rect`
//! at 512×384 (32 light samples): the test pass went from 15 to 7 ms (`izb`) and from 922 to
//! about 240–280 ms (`izb-soft`). Where the soft test's time went on 2026-12-02 (Mesa 25,
//! `bunny-rect`, variants of `test_soft.comp` (now `test_soft.glsl`) built locally and timed
//! interleaved against it, medians of three): of 12.9 M triangle–sample tests, 11.8 M had a
//! sample with open light samples (the umbra skip saves little), 8.7 M passed the plane test and
//! 3.2 M back-projected
//! onto the light's square; cut after the plane test the pass still took 95 of 277 ms (the loop
//! over the cell's triangles itself); on `teapot-rect` the light-sample loop was 84 → 60 ms when
//! removed. Tried and not kept: the test's stages as `WHEN` blocks instead of early returns
//! (1.6× slower), storage-buffer reads instead of texel views (the same), the light-square check
//! before the edge normals (3 %). Also tried (2026-12-02, seventh session, same scene): clusters
//! of 4–32 triangles neighbouring in the Morton order of their centroids as the footprint's unit,
//! each with its box in the light's frame, which a sample back-projects onto the light's square
//! before testing the cluster's triangles (a SIMD group none of whose samples the box reaches
//! skips them). Visibility stayed bit for bit, the footprint pass fell 37 → 11–14 ms and the
//! pairs 587 k → 68–214 k, but the test pass did not get faster (348–532 ms against 366 at one
//! triangle a unit): with 4 triangles a cluster the triangle tests fell 11.8 M → 6.8 M, yet the
//! boxes (grown by their whole extent, no edge test) put pairs in 3× as many cells' work items
//! (8.8 k → 28 k), and a box passes for the group whenever one of its 8 samples is reached;
//! larger clusters made more tests, not fewer. With each cluster's entry carrying the mask of its
//! triangles whose own footprint reaches the cell (so the cells and items stay nearly those of
//! single triangles: 8.8 k → 10.4 k items), 4 triangles a cluster cut the triangle tests to
//! 4.9 M and the pairs to 181 k, yet interleaved medians of five gave the test pass 296 → 274 ms
//! on `bunny-rect` and 90 → 80 ms on `teapot-rect`, while the footprint pass (four triangles
//! tested per cell) rose 33 → 51 and 9 → 31 ms: no net gain. The test pass's time is not
//! proportional to its triangle tests (−58 % of them, −7 % of time) — the per-entry and
//! per-item work dominates on lavapipe.
//! **Triangles eight at a time** (`triangle_batch`, 2026-12-03): a texel fetch on lavapipe is a
//! gather over the SIMD lanes whatever its address, so a uniform triangle cost four gathers per
//! triangle; now each lane fetches and sets up one triangle of a batch of eight (its plane, the
//! light's side of it, its projected box) and the batch goes round the lanes by
//! `subgroupShuffle`s in the list's order (the host takes this only where a subgroup holds a
//! whole workgroup with shuffles, and the shader fails the frame, `batch_lanes`, if its lanes are
//! not 0–7). With the set-up per lane, `izb-soft` checks per sample which of the batch's
//! triangles its own footprint reaches (the footprint pass's test for the sample's projection
//! and depth instead of its cell's), ORs the lanes' sets, and tests only those: on `bunny-rect`
//! the triangle–sample tests fell 12.9 M → 3.5 M and the exact rays 648 k → 92 k (the cut ones
//! were the ambiguous strata of triangles that could not reach the sample), the visibility bit
//! for bit the same. Interleaved medians: `izb-soft`'s test pass 307 → 246 ms from the batch
//! alone, → ~210 with the check (teapot 82 → 58); `izb`'s 17.6 → 10.8 ms. A mask box made by
//! arithmetic when one word holds the samples (columns' bits times the rows' first bits) instead
//! of the row loop: ~6 %; and with one word no mask-word loop around the strata at all (a
//! loop of one pass still costs the SIMD group its mask bookkeeping on lavapipe): the test pass
//! 205 → 151 ms on `bunny-rect` and 54 → 46 on `teapot-rect` (interleaved medians of five,
//! 2026-12-03; the 32-sample default is one word). Tried then, not kept (interleaved A/Bs, no gain
//! beyond the noise): the tangent-plane test of every stratum once per item instead of in the
//! strata loop, `subgroupBroadcast` for the batch instead of `subgroupShuffle`, an `if` instead of
//! the `WHEN` around a kept test (no gain then; 9 % with the others, **Branches**), and the
//! footprint-check loop unrolled (the bunny's pass 15 % slower). Counted then on `teapot-rect` /
//! `bunny-rect`: of the kept tests, 17 k / 25 k are cut by the triangle's plane and 52 k / 122 k
//! project off the light; 0.34 M / 1.34 M find every stratum of their box decided already. Then
//! `perf` on the running process with the JIT
//! code disassembled by `gdb` (GALLIVM has no symbol map) showed the strata loop's
//! `int((bit + ½) · 1/n_a)` as eight scalar conversions with compares and conditional moves (LLVM
//! 15's split of the saturating `fptosi.sat`): `small_int` (`glsl/include/small_int.glsl`) for it
//! and the box's strata made the bunny's test pass 173 → 148 ms and the teapot's 42 → 40. The
//! rest of the loop is spread thin (no instruction above 1 % of the samples; many stack spills).
//! The same helper in `pvssm`'s filter (per kernel column, not per texel) was not faster, and a
//! `WHEN` around its page lookup made the filter 20 % slower. Tried, not kept: each lane taking
//! its own next kept triangle (shuffles with per-lane indices: fewer passes, but the lanes'
//! tests diverge — no gain) and the exact ray test behind a `WHEN` (slower again, as in the first
//! version), and the check grown by only
//! the part of the light still open for the sample (the box of its unblocked strata, recomputed
//! once a batch): tests 3.59 M → 2.90 M on `bunny-rect` and 1.46 M → 1.04 M on `teapot-rect`, the
//! visibility the same, but two interleaved A/Bs of five gave the bunny's test pass −11 % and
//! +10 % and the teapot's ±2 % — the per-batch recomputation eats the saving; and the
//! vertices' light-frame (a, b) set up per lane and shuffled with the batch, so a kept test's
//! back-projection is three interpolations instead of three projections: −1 to −2 %, within the
//! noise (same visibility), not kept; and each cell's samples grouped by depth in the scatter
//! (those nearer than the middle of the cell's depth range from the front, the rest from the
//! back, so an item's lanes keep similar triangles: the kept-triangle loop made 857 k group
//! passes for 3.5 M lane tests on `bunny-rect`): the same test-pass time in an interleaved A/B
//! of six, not kept. With the check,
//! the grid hardly changes the tests, so `izb-soft` defaults to 64 cells with a rect light.
//! **Branches** (2026-12-03, Mesa 25): the `WHEN` loops of one pass, kept from Mesa 22.3, cost the
//! SIMD group more than `if`s, which this lavapipe skips when no lane takes them. On `bunny-rect`,
//! `izb-soft`'s test pass in interleaved medians of three (`tools/ab.py scenes/bunny-rect.toml
//! izb-soft BEFORE AFTER --pass test`): the half-plane branch (1 % of the 3.59 M tests, counted) as
//! an `if` 163.5 → 142.5 ms, the kept test as an `if` 144.0 → 131.5, and the exact ray test (93.8 k
//! of them) as an `if` on the band instead of following two `continue`s 133.4 → 114.1; at 128 light
//! samples 308 → 229 ms (one run each), with `triangle_batch = 0` 250 → 187. `izb`'s test pass:
//! 11.0 → 8.9 ms (medians of five). The visibility is the same bit for bit (the `visibility.exr` of
//! both scenes and both techniques, of 128 samples and of the unbatched pass). The tangent-plane
//! `continue` as an `if` as well: no change over five rounds, not kept. Cut-down variants then
//! (bunny, A/Bs of three against the full pass): with no test at all, the batch loop and the
//! footprint checks take 35 ms of 120 (29 of 111 in a second A/B, where dropping the kept-triangle
//! loop too left 31: its shuffles cost nothing); with everything but the strata loop, 51 of 112;
//! without the exact rays, no change. So of the soft test ~60 ms is the strata loop (a light
//! sample's jittered point and its tangent-plane and edge distances: ~180 vector instructions to
//! the tangent-plane test alone in the JIT code, `tools/jit-profile.sh`, no scalar code), ~35 the
//! loops around the tests and ~17 the tests' set-up (the back-projection onto the light).
//! **Strata loop, lighter** (2026-12-03): the tangent-plane test (and its light-sample point in
//! 3-D) only under an `if` on the samples whose light straddles their plane, the projected edges
//! as affine functions (two FMAs a distance), the pattern's uniforms read once, and the edges
//! scaled by their L1 length instead of normalised (no square roots; the band widens by at most
//! √2, so exact rays 93.8 k → 104.7 k): test pass 113.3 → 103.9 ms minimum, 114.9 → 104.9
//! lower quartile over ten interleaved rounds (`tools/ab.py`, medians 151.6 and 121.3: the VM
//! again), the visibility bit for bit the same (both scenes; 128 and 1024 samples, `jitter = 0`
//! and the unbatched pass on the bunny). Then the edges set up only for a box with light
//! samples still open (a third of the bunny's tests have none, blocked by earlier triangles):
//! teapot-rect's test pass 37.8 → 30.4 ms minimum, 40.2 → 35.0 lower quartile (six rounds),
//! bunny-rect's 102.9 → 101.6 and 103.1 → 101.9, the same bits. Tried, not kept: light samples
//! beyond the band decided a lattice row at a time with `jitter = 0` (along a row an edge's
//! distance is affine in the column: one division an edge instead of a pass a sample; the same
//! bits) — 20 % slower on the bunny, as a test has only 1.5 open candidates on average (3.09 M
//! for 2.10 M tests with any, counted), fewer than the rows' fixed cost; the strata's cells
//! classified against the edges first (only 13 % of the bunny's candidates, 39 % of the
//! teapot's, lie in a cell wholly outside an edge or inside all three, counted), not tried.
//! **Uniform reads** (2026-12-03): on lavapipe every read of the parameter block carries a
//! bounds check, and the per-sample footprint check (eight a batch) and the back-projection
//! (three a test) read the light's frame from it each time. Read once into invocation globals:
//! test pass 113.8 → 98.1 ms minimum, 117.9 → 100.7 lower quartile on bunny-rect (six interleaved
//! rounds), the same bits (both rect scenes, spot-point, thin-bars, `grid:20000@rect`; 7, 128,
//! 1024 samples, `jitter = 0`, unbatched). The light's view matrix and grid map read once for the
//! per-batch set-up as well: no gain (98.1 vs 94.1 minimum, six rounds), not kept. The check
//! grown by the open part of the light again, exactly (the corners of the open strata's box in
//! the light's view space; set again at a batch's start only when the sample decided light
//! samples since): tests 3.59 M → 3.18 M on the bunny, 1.46 M → 1.31 M on the teapot, the same
//! bits, but the test pass 97.6 → 105.8 ms minimum on the bunny (lower quartile 115.0 → 109.0)
//! and 37.8 → 41.1 on the teapot, six rounds each: the tests it drops are the cheap ones. Not kept.
//! Where the tests go (counted at the pass's end, bunny-rect): 3.51 M of the 3.59 M are made by
//! samples that end with some light sample blocked or behind their plane (14.7 k of the 124 k
//! view samples; the lit ones make 2 %), 0.40 M by the umbra's 8.5 k — so ~500 a penumbra
//! sample, each against a triangle whose projection overlaps the light. Fewer of those needs
//! triangles culled in groups (a group's projection against the open strata) or a one-sided
//! test on closed meshes, not a cheaper per-sample check (teapot: 1.40 M of 1.46 M, umbra 0.59 M).
//! **Where the time goes** (2026-12-04, bunny-rect, jittered, the test pass's minimum over
//! interleaved rounds against cut-down shaders, before the work items were dealt across threads):
//! no triangle batch at all 8.5 ms (the 12.1 k workgroups' own cost), batches read and set up
//! but nothing checked or tested ~29 (of which the set-up ~3: the loads dominate), plus the
//! per-sample footprint check ~41, the whole pass ~109 — the tests are ~60 % of it. The
//! kept-triangle loop makes 800 k SIMD iterations (748 k with a lane testing, 4.8 lanes of 8
//! each); the strata loop 1.18 M passes in 528 k calls (2.6 lanes a pass). The atomics at the end
//! cost ~1 % and the jitter hash nothing measurable (`jitter=0` the same time before `c27105f`).
//! Tried, not kept: the strata whose jittered light sample lies in the box found by a first
//! loop before the edges are set up (a fifth of the candidates, but the first loop cost what it
//! saved: 100.9 vs 104.4 ms); the one-word path as a compile-time constant (no gain, 112.5 vs
//! 122.3); grids of 32, 48 and 96 cells instead of 64 (all slower in total).
//! **Since** (`39ac6f1`, `0ec0b49`; counters from instrumented builds, times tools/ab.py minima):
//! each lane walks its own kept triangles of a batch (the passes are the busiest lane's count,
//! 801 k → 767 k); with one mask word and jitter, every sample holds its light samples' quarter
//! of their cell on each axis (two bits of the reference's hash a sample and axis, in four
//! words), so only light samples that may lie in the projected triangle's box are decided (2.75 M
//! → 0.99 M, rays 117 k → 98 k: four fifths of the old candidates lay outside the box); the edges
//! are scaled by their L1 lengths, not divided; a sample whose mask is all decided keeps no
//! triangle (passes 767 k → 671 k). Test pass 81 → 70 ms. Of the 3.59 M tests, 2.89 M find
//! strata under the box, 1.40 M after the quarters, and only 0.58 M an undecided one: the pass
//! is now mostly the projection that finds this out (the strata loop with the edges cut out
//! saved 70 → 67 ms). Tried, not kept: the plane-side check moved into the batch's footprint
//! loop (seven more shuffles a triangle: slower, 77 → 82–89 ms); a check of each batch triangle
//! against the item's samples together before the per-sample loop (83 % of the batches'
//! triangles reach none of them, yet 71.3 → 70.2 ms on the bunny and 21.6 → 22.7 on the teapot);
//! a queue of kept triangles across batches (simulated: 677 k passes against 672 k — the lanes
//! keep the same triangles).
//! **The light's coordinates** (2026-12-05): each lane takes its batch triangle's vertices to
//! the light's affine (a, b) once, and a test projects them from the sample's own (a, b) with a
//! subtraction, a division and an fma an axis (no world-space point, no dot products): test
//! pass 60.5 → 58.2 ms minimum on the bunny (four interleaved rounds), the visibility the same
//! byte for byte on nine scenes and knob sets. Tried the same day, not kept: a batch's box in
//! those coordinates projected once per sample, the batch skipped where none of its light
//! samples is open (a fifth of the tests skipped, the pass 58.6 → 66.7 ms); `reaches` narrowed
//! to the cone of the sample's still-open strata (bounds of their columns and rows, refreshed a
//! batch: 12–14 % fewer tests, the pass 59.0 → 60.3 ms at best — the SIMD group runs as long as
//! its busiest lane, and the bounds cost what the tests saved).
//! **Item bounds** (2026-12-05): the footprint pass's count also writes each triangle's grid box
//! grown by the rect light's spread times 1/z_min (`tri_bounds`, 16 B a triangle, plus margins
//! twice the per-sample check's and 10⁻⁵ relative); a work item takes its samples' grid bounds
//! and their smallest 1/z once, and a batch none of whose triangles' bounds — shrunk by that
//! 1/z times the spread, which gives the footprint for the item's deepest sample — meets them
//! is skipped before its vertices are fetched or set up. Every sample's own check would have
//! kept none of those triangles, so the tests are the same in number and result (43 % of the
//! bunny's 346 k batches skipped): test pass 59.9 → 56.5 ms minimum on bunny-rect (four
//! interleaved rounds), 759 → 673 on `grid:1000000@rect`, the teapot unchanged (18.3 / 18.4).
//! Tried the same day, not kept: `reaches` without the shuffles of `every` and z_min (folded
//! into an infinite box and 1/z_min): 59.4 → 59.9 ms, no gain; the per-sample check run only
//! for the batch's triangles whose bounds meet the item's (a loop over their bits instead of
//! all eight): 56.2 → 57.6 ms, slower.
//! **Work items dealt** (`f9ff296`): lavapipe hands each thread one contiguous block of a
//! dispatch's workgroups, and the items in cell order put the penumbra cells' costly items in
//! one; dealt by rows of a 16-row table (`work_item`), each thread takes a share of every part of
//! the grid: test pass 111.1 → 91.7 ms minimum on the bunny, `izb`'s 9.4 → 8.9.
//! **Loop passes** (2026-12-05, second session): cut-down shaders showed an empty pass of the
//! item's batch loop costing ~14 ns on lavapipe (the SIMD group's mask and the loop limiter's
//! count), so: two batches a pass, the per-sample footprint check unrolled with broadcasts, the
//! item's light-sample quarters unrolled and its row starts by doubling shifts, the box's
//! corners as quarter-cell levels (one conversion for stratum and quarter), work items of 512
//! triangles instead of 256 (a cell's samples set up half as often): test pass 54.5 → 47.9 ms
//! minimum on bunny-rect over the six changes, each byte-identical in visibility. Tried that
//! day, not kept: each pair's bound coded beside its index (one fetch a batch check instead of
//! two; the test pass −0.2 ms, the footprint write +1.5); four batches a pass (+1.3 ms); 16
//! triangles a batch, two a lane (+3.3: each shuffle doubled); the batch's light coordinates and
//! normal recomputed per test instead of shuffled (+2.0); the decide loop's first pass peeled
//! (no change); the box of the still-open strata as an early reject (21 % of the candidates
//! rejected, +2 ms for its upkeep); the work item's binary search unrolled (no change for
//! `izb-soft`, −0.1 ms `izb`); the three projections' divisions as one (no change); the bin
//! pass's count and depth added once for a subgroup whose samples share a cell (within noise);
//! each triangle's soft set-up (grid box, plane, light side, light coordinates: 64 B) written
//! by the footprint count and fetched by the batches instead of computed (test −0.9 ms,
//! footprint +0.5: no net gain for the memory). Tried 2026-12-05 (fourth session), not kept: the
//! batch's kept (sample, triangle) pairs dealt to the lanes eight a pass whoever's sample they
//! are (each lane walking its own sample's makes as many passes as the busiest lane keeps:
//! 655 k passes on bunny-rect where dealing needs 430 k), the sample's state and the closed
//! bits going to and from its lane by shuffles — visibility the same, but the test pass only
//! 52.2 → 49.1 ms at the minimum and unchanged at the lower quartile over eight interleaved
//! rounds: the ~45 shuffles a pass (36 cost ~8 ns a pass in a cut-down shader) and the decide
//! loop's passes, each as long as its busiest lane's, take back what the fewer passes save.
//! 2026-12-05 (fifth session), kept: cut-down shaders split the pass (48 ms on bunny-rect) into
//! item set-up 2.8, batch bounds check 4.9, vertices' fetch and set-up 4.7, footprint checks 4.8,
//! kept-triangle shuffles 4 and tests 27; so each invocation takes two samples of its item
//! ([`SOFT_SAMPLES_PER_INVOCATION`]) and a batch's fetch, set-up and broadcasts serve both
//! (test pass 48.4 → 45.1 ms lower quartile, teapot-rect 18.8 → 16.8, `grid:100000@rect`
//! 98.6 → 86.1; visibility byte-identical), and the half-planes' boxes of a triangle not
//! strictly between sample and light are built without branches (~0.5 ms).
//! 5. `resolve`: visibility from the masks.
//!
//! **izb** tests the ray from `o` to the light's centre (a rect light counts as a point at its
//! centre; a sun as its centre direction): visibility is exact per view sample, equal to the
//! ray-cast `reference` with a point light but for rays the two could only decide differently
//! through a triangle the footprint test left out — none, since the footprint is grown by a
//! margin far above its rounding (the tests check bit-equality). Under a rect light or a sun
//! with an extent the engine then scales the centre's answer by the part of the light in front
//! of the sample's tangent plane, as it does every map's (`light_clip`, on by default; the
//! receivers' passes, [`crate::passes::receivers`], skipped under a point light or a hard sun,
//! where that part is 0 or 1 and the bin pass's tangent-plane test already finds the 0s; under
//! the others they store only that part, not the lookup positions a map's lookups read).
//! **izb-soft** keeps a bitmask of
//! `samples` light samples per view sample: an `n_a × n_b` stratified grid over the rect light
//! (n_b the largest divisor of `samples` not above its square root), jittered in its cells by
//! the reference's hash (`glsl/include/light_samples.glsl`), so `samples = N²` draws exactly the
//! reference's N × N points. A triangle back-projected from `o` onto the light (4 half-planes of
//! the light's square: beyond the triangle's plane and inside its three edge planes through
//! `o`, each grown by a tolerance) bounds the light samples it can block; only those of the
//! strata that box touches take the exact ray test. Light samples behind the tangent plane are
//! never tested and count as blocked, as in the reference. Occluder fusion is exact for the
//! chosen samples: the mask is the union of what each triangle blocks. Under a sun disk the light
//! samples are the reference's directions (the same grid taken to the disk by the concentric
//! map, `c + u·d.x + v·d.y` with `|u| = |v|` the tangent of the angular radius): a triangle is
//! projected from `o` onto the plane of directions at unit distance along `c` (or, not strictly
//! in front of `o`, bounded by four half-planes of directions), and each open light sample whose
//! disk point lies in that bound is decided by its edges or the exact ray; a projection holding
//! the whole disk blocks every open light sample at once. The map bends the square's rows, so a
//! box of the disk is no box of strata: the candidates are the strata of the box of the square
//! that holds every point the map takes into the disk's box (`glsl/include/disk_strata.glsl`, from
//! the box's radii and angles; its conservativeness checked on the device by
//! `tests/disk_strata.rs`). The sun's test is a shader of its own (`SUN_DISK`).
//!
//! **Footprints.** A perspective grid coordinate is `(x/z, y/z)` in the light's view space (z
//! the depth), mapped onto `grid × grid` cells over the view samples' bounds
//! ([`crate::passes::ReceiverBounds`]); projections outside clamp to the border cells, which
//! keeps every footprint test conservative. Every point of the segment from `o` to the light
//! centre projects to `o`'s cell, so the hard footprint is the triangle's projection, grown by
//! 0.01 cell. A point x of the segment from `o` (depth z_o) to a light sample at lateral offset
//! ℓ (depth 0) projects to `π(o) + ℓ·(1/z_x − 1/z_o)`, so the soft footprint of a cell is the
//! projection grown by the light's half extents times `1/z_tri − 1/z_cell`, z_tri the triangle's
//! nearest depth and z_cell the cell's deepest sample. Under a sun the grid is orthographic and
//! the rays parallel within the disk's tangent t, so the projection is grown by t·(z_cell −
//! z_tri). A cell whose samples are all nearer the
//! light than the whole triangle is skipped, and so is every cell without samples (work
//! skipping: only cells holding view samples are visited; a triangle with no pair is culled).
//!
//! **Limits.** Pairs beyond `pair_capacity` million are not stored, and the test pass then runs
//! nothing. The frame counted them all, though, so [`crate::ShadowRenderer::render`] rebuilds
//! with room for a quarter more and renders it again ([`Technique::outgrown`]; the bench's rows
//! show the grown knob): a huge light costs a rebuild, never wrong shadows. The pairs and the
//! triangles' vertices (and, in the footprint pass, the cells' counts and depths) are read
//! through texel views, so pairs, three texels a triangle and the grid's cells must fit the
//! device's `maxTexelBufferElements` (2^27 on lavapipe; 65 536 is all Vulkan guarantees): a
//! frame counting more pairs than that is rendered again on a grid half as fine, down to 8
//! cells a side (same result, fewer pairs: bunny-rect's light × 100 counts 138 M on the soft
//! 64² grid, 36 M on 32²), and a technique whose triangles or cells pass it fails to build
//! with [`Error::Unsupported`]. A frame cut short by lavapipe's loop limiter (65 535 loop
//! passes per SIMD group and dispatch) fails with a clear error rather than return wrong
//! shadows. Under a huge light nearly every triangle reaches every sample's footprint, so the
//! test pass grows with samples × triangles. Past about three times the bundled scenes' rect
//! lights, the reference's BVH rays return the same image faster: `izb-soft` at 64 samples is
//! the reference's 8 × 8 byte for byte, 12× faster at × 1 on teapot-rect and 8× slower at × 100
//! (README, "Huge lights"; `tools/izb_crossover.sh`).
//!
//! **Counters**: `view_samples`, `samples_binned`, `behind_tangent_plane` (never binned: V = 0),
//! `cells_used`, `longest_cell` (samples), `pairs` (triangle, cell), `items` (work items of the
//! test pass), `triangles_culled`, `large_triangles`, `huge_triangles`, `sample_tests`
//! (triangle–sample tests), `ray_tests` (exact ray–triangle tests), `overflow_samples`, `lit`,
//! `umbra`, `penumbra`. CPU twin: [`crate::cpu::izb`].

mod knobs;
mod params;
mod setup;

use knobs::{COUNTER_WORDS, MAX_PAIRS, MIN_GRID};
pub use knobs::{IZB, IZB_SOFT};
pub use params::{
    grid_map, sample_grid, soft_item_triangles, spatial_order, IzbParams, IzbPush,
    HARD_ITEM_TRIANGLES, ITEM_SAMPLES, SOFT_ITEM_PASSES, SOFT_SAMPLES_PER_INVOCATION,
};

use super::{read_counters, Technique};
use crate::error::{Error, Result};
use crate::gpu::{Buffer, Context, DescriptorSet, Pipeline, Recorder, TexelView};
use crate::kernels::scan::{Scan, ScanBinding, ScanKind};

/// Workgroups of the large-footprint passes (`LARGE_GROUPS` in `glsl/izb/izb.glsl`).
const LARGE_GROUPS: u32 = 1024;

struct Izb<'a> {
    ctx: Context,
    name: &'static str,
    view_size: [u32; 2],
    triangles: u32,
    bin: (Pipeline, DescriptorSet),
    scatter: (Pipeline, DescriptorSet),
    footprint: (Pipeline, DescriptorSet),
    args_pass: (Pipeline, DescriptorSet),
    test: (Pipeline, DescriptorSet),
    resolve: (Pipeline, DescriptorSet),
    scan: Scan,
    cell_scan: ScanBinding,
    pair_scan: ScanBinding,
    item_scan: ScanBinding,
    /// Cells a side (the `grid` knob resolved); the grid's cells and the overflow cell are
    /// `grid² + 1`.
    grid: u32,
    cell_count: Buffer,
    cell_depth: Buffer,
    tri_cells: Buffer,
    cell_tris: Buffer,
    cell_cursor: Buffer,
    masks: Buffer,
    counters: Buffer,
    args: Buffer,
    _views: [TexelView; 5],
    _buffers: Vec<Buffer>,
    _visibility: &'a crate::gpu::Image,
}

/// Dispatches `pass` with the phase as its push constant when the shader declares one.
fn run(
    rec: &mut Recorder<'_>,
    pass: &(Pipeline, DescriptorSet),
    phase: u32,
    threads: [u32; 3],
) -> Result<()> {
    if pass.0.push_constant_size() > 0 {
        rec.dispatch(&pass.0, &pass.1, &IzbPush { phase }, threads)
    } else {
        rec.dispatch(&pass.0, &pass.1, &(), threads)
    }
}

impl Technique for Izb<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        let [w, h] = self.view_size;
        let pixels = [w, h, 1];
        rec.pass("bin", |rec| {
            rec.fill(&self.cell_count, 0);
            rec.fill(&self.cell_depth, 0);
            rec.fill(&self.counters, 0);
            rec.fill(&self.masks, 0);
            run(rec, &self.bin, 0, pixels)?;
            self.scan
                .record(rec, &self.cell_scan, ScanKind::Exclusive)?;
            run(rec, &self.scatter, 0, pixels)
        })?;
        rec.pass("footprint", |rec| {
            rec.fill(&self.cell_tris, 0);
            rec.fill(&self.cell_cursor, 0);
            let tris = [self.triangles, 1, 1];
            let large = [LARGE_GROUPS * 64, 1, 1];
            if self.triangles > 0 {
                rec.fill(&self.tri_cells, 0);
                run(rec, &self.footprint, 0, tris)?;
                run(rec, &self.footprint, 1, large)?;
            }
            self.scan
                .record(rec, &self.pair_scan, ScanKind::Exclusive)?;
            run(
                rec,
                &self.args_pass,
                0,
                [(self.grid * self.grid + 1).min(64 * 1024), 1, 1],
            )?;
            self.scan
                .record(rec, &self.item_scan, ScanKind::Exclusive)?;
            if self.triangles > 0 {
                run(rec, &self.footprint, 2, tris)?;
                run(rec, &self.footprint, 3, large)?;
            }
            run(rec, &self.args_pass, 1, [1, 1, 1])
        })?;
        rec.pass("test", |rec| {
            rec.dispatch_indirect(&self.test.0, &self.test.1, &(), &self.args, 0)
        })?;
        rec.pass("resolve", |rec| run(rec, &self.resolve, 0, pixels))
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let words = read_counters(&self.ctx, &self.counters, &COUNTER_WORDS)?;
        let get = |n: &str| word(&words, n);
        let name = self.name;
        if get("cut") > 0 {
            return Err(Error::Shader {
                name: format!("izb/{name}"),
                message: format!(
                    "the driver's loop limiter cut {} invocations short: the frame is wrong \
                     (a smaller `grid` or fewer `samples` shortens the loops)",
                    get("cut")
                ),
            });
        }
        if get("batch_lanes") > 0 {
            return Err(Error::Unsupported {
                device: self.ctx.info().name.clone(),
                feature: format!(
                    "{name}'s batched test pass: {} of its workgroups were not one subgroup's \
                     lanes 0-7 (set `triangle_batch = 0`)",
                    get("batch_lanes")
                ),
            });
        }
        if get("pair_overflow") > 0 {
            // Only a recorded frame gets here: `ShadowRenderer::render` grows and renders again.
            return Err(Error::Parameter {
                technique: name.to_string(),
                message: format!(
                    "{} (triangle, cell) pairs exceed pair_capacity: the frame is wrong \
                     (`ShadowRenderer::grow` rebuilds with room for them; or raise \
                     `pair_capacity`, millions, or lower `grid`)",
                    pair_count(&words)
                ),
            });
        }
        let mut out = Vec::new();
        for (k, v) in &words {
            match k.as_str() {
                "sample_tests" | "ray_tests" | "pairs" => {
                    out.push((k.clone(), v + (get(&format!("{k}_hi")) << 32)));
                }
                "sample_tests_hi" | "ray_tests_hi" | "pairs_hi" | "max_depth_bits" | "cut"
                | "pair_overflow" | "batch_lanes" => {}
                _ => out.push((k.clone(), *v)),
            }
        }
        Ok(out)
    }

    fn buffers(&self) -> Vec<(&'static str, &Buffer)> {
        // Per cell: its (triangle, cell) pairs, whose total the frame's `pairs` counts.
        vec![("cell_triangles", &self.cell_tris)]
    }

    fn outgrown(&self) -> Result<Option<(&'static str, f64)>> {
        let words = read_counters(&self.ctx, &self.counters, &COUNTER_WORDS)?;
        let get = |n: &str| word(&words, n);
        if get("pair_overflow") == 0 {
            return Ok(None);
        }
        let (pairs, info) = (pair_count(&words), self.ctx.info());
        let limit = u64::from(info.max_texel_buffer_elements);
        room_for(pairs, limit, self.grid)
            .map(Some)
            .ok_or_else(|| Error::Unsupported {
                device: info.name.clone(),
                feature: format!(
                    "{}'s {pairs} (triangle, cell) pairs at the coarsest grid: one texel \
                     buffer holds {limit} (maxTexelBufferElements), `pair_capacity` {MAX_PAIRS}",
                    self.name
                ),
            })
    }
}

/// Counter word `name` of a frame's words (0 where there is none).
fn word(words: &[(String, u64)], name: &str) -> u64 {
    words.iter().find(|(k, _)| k == name).map_or(0, |(_, v)| *v)
}

/// The frame's (triangle, cell) pairs from its counter words: counted in 64 bits, as past 2^32
/// the scan's 32-bit starts wrap (`glsl/izb/args.comp`).
fn pair_count(words: &[(String, u64)]) -> u64 {
    word(words, "pairs") + (word(words, "pairs_hi") << 32)
}

/// The knob to rebuild with when a frame counted `pairs` pairs at `grid` cells a side and one
/// texel view reads at most `limit`: room for a quarter more (so that a light or camera moving
/// on does not rebuild it frame after frame) within the limit and the knob's range; past either
/// the grid halved, as coarser cells make fewer pairs (a triangle spanning the grid, as under a
/// huge light, pairs with a quarter as many) and the result is the same — every (triangle,
/// sample) test still runs, in other cells. `None` at the coarsest grid.
fn room_for(pairs: u64, limit: u64, grid: u32) -> Option<(&'static str, f64)> {
    let most = limit.min(MAX_PAIRS);
    if pairs <= most {
        let room = (pairs + pairs / 4).min(most);
        Some(("pair_capacity", room as f64 / 1e6))
    } else if grid / 2 >= MIN_GRID {
        Some(("grid", f64::from(grid / 2)))
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Room for a quarter more, in whole pairs once the knob's millions are rounded back, never
    /// past the device's limit or the knob's most; past them the grid halves down to its
    /// least, then nothing holds.
    #[test]
    fn room_for_grows_then_coarsens() {
        let limit = 1 << 27;
        let (knob, millions) = room_for(1_000_001, limit, 64).expect("fits");
        assert_eq!(knob, "pair_capacity");
        assert_eq!((millions * 1e6).round() as u64, 1_250_001);
        let (_, millions) = room_for(limit - 10, limit, 64).expect("fits");
        assert_eq!((millions * 1e6).round() as u64, limit);
        assert_eq!(room_for(limit + 1, limit, 64), Some(("grid", 32.0)));
        assert_eq!(room_for(limit + 1, limit, 17), Some(("grid", 8.0)));
        assert_eq!(room_for(limit + 1, limit, 15), None);
        assert_eq!(room_for(limit + 1, limit, MIN_GRID), None);
        // A device whose texel views take more than the knob's most: the knob's most decides.
        let (_, millions) = room_for(MAX_PAIRS - 1, 1 << 32, 64).expect("fits");
        assert_eq!((millions * 1e6).round() as u64, MAX_PAIRS);
        assert_eq!(room_for(MAX_PAIRS + 1, 1 << 32, 64), Some(("grid", 32.0)));
    }
}
