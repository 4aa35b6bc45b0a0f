//! Reading back a frame's page state: counters, and the lists, table, bins and slots the tests
//! compare with the CPU twin.

use super::{
    AtlasDepths, VirtualPages, APPEND_REST, APPEND_ROOT, FIT_LEVEL, FIT_WHOLE_END, LEVEL_PAIRS,
    PAGE_COUNTER_NAMES, REWALK_FINER, REWALK_ROOT,
};
use crate::error::Result;
use crate::gpu::Buffer;

impl VirtualPages<'_> {
    /// Counters of the last frame: [`PAGE_COUNTER_NAMES`], then `drawn_pages` (allocated in
    /// both rounds, less those dropped for full bins) and `triangles_culled` (scene triangles
    /// not drawn into a drawn page, summed over them: the work the binning skipped).
    pub fn counters(&self) -> Result<Vec<(String, u64)>> {
        let mut out =
            crate::techniques::read_counters(&self.ctx, &self.counters, &PAGE_COUNTER_NAMES)?;
        let get = |name: &str| out.iter().find(|(n, _)| n == name).map_or(0, |(_, v)| *v);
        let drawn = (get("allocated_pages") + get("refine_allocated_pages"))
            .saturating_sub(get("bin_overflow_pages"));
        // A pair the walk covered itself is drawn as much as one binned.
        let drawn_pairs = get("triangles_binned") + get("walk_covered_pairs");
        let culled = (u64::from(self.push.triangles) * drawn).saturating_sub(drawn_pairs);
        out.push(("drawn_pages".into(), drawn));
        out.push(("triangles_culled".into(), culled));
        Ok(out)
    }

    /// The atlas's depths row by row (`pool_pages` slots of `page_size`² texels, slot `s` at
    /// column `s % atlas_cols`, row `s / atlas_cols`) and its width and height: from the image,
    /// or from the compute raster's buffer (its quads put back in rows) where that is the
    /// atlas. For tests and debug images.
    pub fn read_atlas(&self) -> Result<(Vec<f32>, (u32, u32))> {
        let (width, height) = self.desc.atlas_size();
        let AtlasDepths::Image(image) = &self.atlas else {
            // In 2 × 2 quads (`atlas_word` in glsl/include/pages.glsl): back to rows.
            let quads = crate::gpu::f32s(&self.ctx.read_buffer(&self.depth_bits)?);
            let (w, h) = (width as usize, height as usize);
            let mut rows = vec![0.0f32; w * h];
            for (q, quad) in quads.chunks_exact(4).enumerate() {
                let (x, y) = (2 * (q % (w / 2)), 2 * (q / (w / 2)));
                rows[y * w + x] = quad[0];
                rows[y * w + x + 1] = quad[1];
                rows[(y + 1) * w + x] = quad[2];
                rows[(y + 1) * w + x + 1] = quad[3];
            }
            return Ok((rows, (width, height)));
        };
        let bytes = self.ctx.read_image(image)?;
        Ok((crate::gpu::f32s(&bytes), (width, height)))
    }

    /// The last frame's compacted page list (the marked entries, ascending): for tests.
    pub fn read_page_list(&self) -> Result<Vec<u32>> {
        self.read_compacted(&self.list, &self.count)
    }

    /// The last frame's compacted refinement list (ascending): for tests.
    pub fn read_refine_list(&self) -> Result<Vec<u32>> {
        self.read_compacted(&self.refine_list, &self.refine_count)
    }

    /// A compaction's output: the first `count[0]` words of `list`.
    fn read_compacted(&self, list: &Buffer, count: &Buffer) -> Result<Vec<u32>> {
        let n = crate::gpu::u32s(&self.ctx.read_buffer(count)?)
            .first()
            .copied()
            .unwrap_or(0) as usize;
        let mut list = crate::gpu::u32s(&self.ctx.read_buffer(list)?);
        list.truncate(n);
        Ok(list)
    }

    /// The last walk's level mask per cluster (`glsl/pages/cluster_levels.comp`): for tests.
    pub fn read_cluster_masks(&self) -> Result<Vec<u32>> {
        let clusters = self
            .push
            .triangles
            .div_ceil(crate::passes::CLUSTER_TRIANGLES) as usize;
        let mut masks = crate::gpu::u32s(&self.ctx.read_buffer(&self.cluster_mask)?);
        masks.truncate(clusters);
        Ok(masks)
    }

    /// The page table after the last frame (slot + 1 or 0 per entry): for tests.
    pub fn read_table(&self) -> Result<Vec<u32>> {
        Ok(crate::gpu::u32s(&self.ctx.read_buffer(&self.table)?))
    }

    /// After the last frame, when round 0's appended bins overflowed: the levels
    /// `glsl/pages/bin_fit.comp` kept and the non-root pairs per level (level 0 first) that the
    /// counting walk found; `None` when the bins fit. For tests.
    pub fn read_bin_fit(&self) -> Result<Option<(crate::cpu::pages::BinFit, Vec<u64>)>> {
        let cursors = crate::gpu::u32s(&self.ctx.read_buffer(&self.bin_cursor)?);
        let at = self.desc.pool_pages as usize;
        let fit_plus1 = cursors[at + FIT_LEVEL];
        if fit_plus1 == 0 {
            return Ok(None);
        }
        let pairs = (0..self.push.levels as usize)
            .map(|l| u64::from(cursors[at + LEVEL_PAIRS + l]))
            .collect();
        let fit = crate::cpu::pages::BinFit {
            whole_from: fit_plus1 - 1,
            whole_entries: u64::from(cursors[at + FIT_WHOLE_END]),
        };
        Ok(Some((fit, pairs)))
    }

    /// The last frame's bins as (triangle, slot) pairs, slot by slot: for tests.
    pub fn read_bins(&self) -> Result<Vec<(u32, u32)>> {
        let raw = crate::gpu::u32s(&self.ctx.read_buffer(&self.entries)?);
        let pairs = |range: std::ops::Range<usize>| -> Vec<(u32, u32)> {
            raw[2 * range.start..2 * range.end]
                .chunks_exact(2)
                .map(|p| (p[0], p[1]))
                .collect()
        };
        if self.appends() {
            // The root's region, then the others' from entry `triangles` on (bin.comp mode 2).
            let cursors = crate::gpu::u32s(&self.ctx.read_buffer(&self.bin_cursor)?);
            let pool = self.desc.pool_pages as usize;
            let triangles = self.push.triangles as usize;
            let room = self.push.capacity as usize - triangles;
            let word = |k: usize| cursors[pool + k] as usize;
            // After the walks of an overflow (bin_fit.comp), the last one's entries: the root's,
            // then the levels kept whole and the finer levels' that fitted.
            let (root, rest) = if word(FIT_LEVEL) != 0 {
                (word(REWALK_ROOT), word(FIT_WHOLE_END) + word(REWALK_FINER))
            } else {
                (word(APPEND_ROOT), word(APPEND_REST))
            };
            let mut bins = pairs(0..root);
            bins.extend(pairs(triangles..triangles + rest.min(room)));
            bins.sort_unstable_by_key(|&(t, s)| (s, t));
            return Ok(bins);
        }
        let counts = crate::gpu::u32s(&self.ctx.read_buffer(&self.bin_count)?);
        let total: u64 = counts.iter().map(|&c| u64::from(c)).sum();
        let n = total.min(u64::from(self.push.capacity)) as usize;
        Ok(pairs(0..n))
    }

    /// The bands each allocated slot (both rounds) was drawn over after the last frame, in slot
    /// order (`glsl/include/pages.glsl`): for tests.
    pub fn read_slot_bands(&self) -> Result<Vec<u32>> {
        let slots = self.read_slots()?.len();
        let mut bands = crate::gpu::u32s(&self.ctx.read_buffer(&self.slot_bands)?);
        bands.truncate(slots);
        Ok(bands)
    }

    /// (level, page x, page y, entry) of each allocated slot (both rounds) after the last
    /// frame: for tests.
    pub fn read_slots(&self) -> Result<Vec<[u32; 4]>> {
        let counters = self.counters()?;
        let get = |name: &str| {
            counters
                .iter()
                .find(|(n, _)| n == name)
                .map_or(0, |(_, v)| *v as usize)
        };
        let allocated = get("allocated_pages") + get("refine_allocated_pages");
        let raw = crate::gpu::u32s(&self.ctx.read_buffer(&self.slot_info)?);
        Ok(raw
            .chunks_exact(4)
            .take(allocated)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect())
    }
}
