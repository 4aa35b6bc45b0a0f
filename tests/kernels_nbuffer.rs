//! N-buffers and min/max pyramids on the GPU against brute force, under validation: levels and
//! queries in both layouts, the staged walk within the device's limits, odd sizes.

mod common;

use ash::vk;
use penumbra::cpu::nbuffer::{brute_minmax, full_levels};
use penumbra::gpu::{Context, Image};
use penumbra::kernels::minmax::MinMaxPyramid;
use penumbra::kernels::nbuffer::{NBuffer, NBufferLayout};

use common::kernels_sat::{float_image, Rng};

/// Random floats in [0, 1) uploaded as R32F or D32.
fn random_source(
    ctx: &Context,
    format: vk::Format,
    w: u32,
    h: u32,
    seed: u64,
) -> (Vec<f32>, Image) {
    let mut rng = Rng(seed);
    let data: Vec<f32> = (0..w * h).map(|_| rng.unit()).collect();
    let image = float_image(ctx, format, w, h, &data);
    (data, image)
}

/// The staged walk needs a level within one storage-buffer binding: past it `best` walks with
/// image stores and asking for the staged walk is a clear error.
#[test]
fn staged_nbuffer_follows_the_device_limits() {
    let ctx = common::context();
    let range = u64::from(ctx.info().max_storage_buffer_range);
    let side = ((range / 8) as f64).sqrt() as u32 + 1;
    let staged = NBufferLayout::StagedWalk;
    assert!(
        !staged.supported(&ctx, side, side),
        "{side}² past {range} bytes"
    );
    assert_ne!(NBufferLayout::best(&ctx, side, side), staged);
    if ctx.info().runs_workgroups_on_cpu_threads() && staged.supported(&ctx, 64, 64) {
        assert_eq!(NBufferLayout::best(&ctx, 64, 64), staged);
    }
    // Asking for it there is a clear error, refused before any level is made. A source as wide
    // as the device allows, just past the range (never uploaded: nothing reads it), where the
    // device can make one (a GPU's range may outgrow any 2D image).
    let width = ctx.info().max_image_dimension_2d;
    let height = range / 8 / u64::from(width) + 1;
    if height > u64::from(width) {
        common::assert_clean(&ctx.validation());
        return;
    }
    let height = height as u32;
    let usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST;
    let desc = penumbra::gpu::ImageDesc::new_2d(vk::Format::R32_SFLOAT, width, height, usage);
    let source = Image::new(&ctx, "past the range", desc).expect("source");
    let err = NBuffer::with_layout(&ctx, &source, Some(1), staged).err();
    assert!(
        matches!(err, Some(penumbra::Error::Unsupported { .. })),
        "{err:?}"
    );
    drop(source);
    common::assert_clean(&ctx.validation());
}

#[test]
fn nbuffer_levels_and_queries_match_brute_force() {
    let ctx = common::context();
    // Both layouts; the tiled one with fewer levels than a tile builds (2) and tiles cut by the
    // edges (300 and 173 are not multiples of 16); odd widths and heights below a chain's rows
    // (the walk's first level takes its rows two at a time).
    let (r32, d32) = (vk::Format::R32_SFLOAT, vk::Format::D32_SFLOAT);
    let (walk, tiled, odd) = (NBufferLayout::Walk, NBufferLayout::Tiled, (300, 173));
    let staged = NBufferLayout::StagedWalk;
    let mut cases = vec![
        (odd, r32, None, walk),
        (odd, d32, None, walk),
        (odd, r32, Some(2), walk),
        ((301, 5), d32, None, walk),
        ((7, 2), r32, None, walk),
        // Levels 3 and 4 leave fewer rows to a residue (mod d) than a chain walks.
        ((260, 16), r32, None, walk),
        (odd, r32, None, tiled),
        (odd, d32, Some(4), tiled),
        (odd, r32, Some(2), tiled),
    ];
    // The staged walk where the device has it (lavapipe does): the same cases as the walk's,
    // one level alone among them (its first dispatch binds one buffer for both outputs).
    if staged.supported(&ctx, odd.0, odd.1) {
        cases.extend([
            (odd, r32, None, staged),
            (odd, d32, None, staged),
            (odd, r32, Some(1), staged),
            (odd, r32, Some(2), staged),
            ((301, 5), d32, None, staged),
            ((7, 2), r32, None, staged),
            ((260, 16), r32, None, staged),
        ]);
    }
    for ((w, h), format, max_level, layout) in cases {
        let (data, source) = random_source(&ctx, format, w, h, 21);
        let nb = NBuffer::with_layout(&ctx, &source, max_level, layout).expect("nbuffer");
        ctx.submit(None, |rec| nb.record(rec)).expect("build");
        assert_eq!(nb.max_level, max_level.unwrap_or(full_levels(w, h) - 1));
        let cpu = penumbra::cpu::nbuffer::build(&data, w, h, nb.max_level);
        for l in 1..=nb.max_level {
            assert!(
                nb.read_level(l).expect("read") == cpu.levels[l as usize],
                "{format:?} {layout:?} level {l}"
            );
        }
        let mut rng = Rng(5);
        let mut squares: Vec<[i32; 3]> = (0..3000)
            .map(|_| {
                [
                    rng.below(w + 20) - 10,
                    rng.below(h + 20) - 10,
                    1 + rng.below(200),
                ]
            })
            .collect();
        squares.extend([
            [0, 0, h as i32],
            [0, 0, 1000],
            [w as i32 - 1, h as i32 - 1, 1],
            [-5, 3, 5],
            [127, 45, 128],
        ]);
        let gpu = nb.query(&squares).expect("query");
        for (s, got) in squares.iter().zip(&gpu) {
            let hi = [s[0] + s[2] - 1, s[1] + s[2] - 1];
            let want = brute_minmax(&data, w, h, [s[0], s[1]], hi);
            assert_eq!(*got, want, "{format:?} L{} square {s:?}", nb.max_level);
            assert_eq!(
                cpu.minmax_square([s[0], s[1]], s[2]),
                want,
                "CPU twin, square {s:?}"
            );
        }
    }
    // One texel wide: no level above the source, queries read it alone.
    let (data, source) = random_source(&ctx, vk::Format::R32_SFLOAT, 1, 37, 2);
    let nb = NBuffer::with_layout(&ctx, &source, None, NBufferLayout::Tiled).expect("nbuffer");
    assert_eq!(nb.max_level, 0);
    ctx.submit(None, |rec| nb.record(rec)).expect("build");
    let squares = [[0, 0, 1], [0, 5, 4], [-3, 30, 10]];
    for (s, got) in squares.iter().zip(nb.query(&squares).expect("query")) {
        let hi = [s[0] + s[2] - 1, s[1] + s[2] - 1];
        assert_eq!(
            got,
            brute_minmax(&data, 1, 37, [s[0], s[1]], hi),
            "1x37 square {s:?}"
        );
    }
    drop(nb);
    common::assert_clean(&ctx.validation());
}

#[test]
fn pyramid_matches_brute_force_on_odd_sizes() {
    let ctx = common::context();
    for (format, w, h) in [
        (vk::Format::R32_SFLOAT, 1, 1),
        (vk::Format::R32_SFLOAT, 1, 37),
        (vk::Format::R32_SFLOAT, 13, 6),
        (vk::Format::R32_SFLOAT, 257, 129),
        (vk::Format::D32_SFLOAT, 300, 173),
        // The tiny levels' single dispatch (minmax_tail.glsl) from level 2, the earliest it
        // starts, and over a long thin tail of five levels.
        (vk::Format::R32_SFLOAT, 33, 20),
        (vk::Format::R32_SFLOAT, 1000, 3),
    ] {
        let (data, source) = random_source(&ctx, format, w, h, (w * h) as u64);
        let pyramid = MinMaxPyramid::new(&ctx, &source).expect("pyramid");
        ctx.submit(None, |rec| pyramid.record(rec)).expect("build");
        assert_eq!(*pyramid.sizes.last().expect("levels"), (1, 1));
        for (l, &(lw, lh)) in pyramid.sizes.iter().enumerate().skip(1) {
            let level = pyramid.read_level(l as u32).expect("read");
            assert_eq!(level.len(), (lw * lh) as usize);
            let s = 1i32 << l;
            for y in 0..lh as i32 {
                for x in 0..lw as i32 {
                    let want =
                        brute_minmax(&data, w, h, [x * s, y * s], [x * s + s - 1, y * s + s - 1]);
                    assert_eq!(
                        level[(y * lw as i32 + x) as usize],
                        want,
                        "{format:?} {w}x{h} level {l} ({x}, {y})"
                    );
                }
            }
        }
    }
    // Level sizes round up at every step: 13 -> 7 -> 4 -> 2 -> 1.
    assert_eq!(
        penumbra::cpu::minmax::level_sizes(13, 6),
        [(13, 6), (7, 3), (4, 2), (2, 1), (1, 1)]
    );
    common::assert_clean(&ctx.validation());
}
