//! Pass 1 of the `atty` twin (`receivers.comp`): the view samples binned into the map's texels,
//! each texel's nearest and farthest sample and their representatives, and what rounding may
//! change of them (the module note of [`super`]).

use super::*;

/// The receivers' map (`receivers.comp`), per texel row-major.
#[derive(Clone, Debug)]
pub struct ReceiverMap {
    /// The map's side.
    pub size: i32,
    /// The nearest sample's depth bits; [`NONE`] where the texel holds none.
    pub near_bits: Vec<u32>,
    /// The farthest sample's depth bits; 0 where the texel holds none.
    pub far_bits: Vec<u32>,
    /// The nearest representative's pixel index, [`NONE`] for none.
    pub near_pixel: Vec<u32>,
    /// The farthest representative's pixel index, [`NONE`] for none.
    pub far_pixel: Vec<u32>,
    /// Per texel and layer (near, far): the other view samples rounding may make the GPU's
    /// representative (a sample within 2·[`DEPTH_EPSILON`] of the layer's depth, one that
    /// rounding may bin into the texel, the next one where the representative may leave it).
    pub alternatives: Vec<[Vec<u32>; 2]>,
    /// Per texel: whether rounding may move a layer's depth by more than 2·[`DEPTH_EPSILON`]
    /// (a sample that may join the texel beyond its extremes, or a representative that may
    /// leave it).
    pub depth_uncertain: Vec<bool>,
    /// Per texel: whether rounding may leave it empty on one side only.
    pub occupancy_uncertain: Vec<bool>,
}

impl ReceiverMap {
    pub(super) fn index(&self, t: IVec2) -> usize {
        (t.y * self.size + t.x) as usize
    }

    /// The nearest sample depth of texel `t`.
    pub fn near_depth(&self, t: IVec2) -> f32 {
        f32::from_bits(self.near_bits[self.index(t)])
    }

    /// The farthest sample depth of texel `t`.
    pub fn far_depth(&self, t: IVec2) -> f32 {
        f32::from_bits(self.far_bits[self.index(t)])
    }

    /// Whether texel `t` holds a view sample.
    pub fn occupied(&self, t: IVec2) -> bool {
        self.near_pixel[self.index(t)] != NONE
    }

    /// Whether rounding may change anything the lookup reads of texel `t` but its layers'
    /// occlusion (which [`SoftShadowMap::tie`] covers).
    pub(super) fn lookup_uncertain(&self, t: IVec2) -> bool {
        let k = self.index(t);
        self.occupancy_uncertain[k] || self.depth_uncertain[k]
    }
}

/// Whether `x` is within `eps` of an integer.
pub(super) fn near_integer(x: f32, eps: f32) -> bool {
    (x - x.round()).abs() <= eps
}

/// The texel a shadow coordinate bins into, and the texels rounding may bin it into instead.
fn bins(c: Vec4, n: i32, dc: f32) -> (IVec2, Vec<IVec2>) {
    let t = c
        .xy()
        .floor()
        .as_ivec2()
        .min(IVec2::splat(n - 1))
        .max(IVec2::ZERO);
    let step = |x: f32, i: i32| -> Vec<i32> {
        let mut alt = Vec::new();
        if (x - x.round()).abs() <= dc {
            let e = x.round() as i32;
            // The edge at e separates texels e − 1 and e.
            for k in [e - 1, e] {
                if k != i && (0..n).contains(&k) {
                    alt.push(k);
                }
            }
        }
        alt
    };
    let (ax, ay) = (step(c.x, t.x), step(c.y, t.y));
    let mut alt = Vec::new();
    for &x in &ax {
        alt.push(IVec2::new(x, t.y));
    }
    for &y in &ay {
        alt.push(IVec2::new(t.x, y));
        for &x in &ax {
            alt.push(IVec2::new(x, y));
        }
    }
    (t, alt)
}

/// Whether the shadow coordinate `c` lies within rounding of the map's border or depth range
/// (the GPU's `inside_map` may decide the other way).
pub(super) fn on_border(c: Vec4, n: i32, dc: f32) -> bool {
    let edge = |x: f32, end: f32, eps: f32| x.abs() <= eps || (x - end).abs() <= eps;
    c.w > 0.0
        && (edge(c.x, n as f32, dc) || edge(c.y, n as f32, dc) || edge(c.z, 1.0, DEPTH_EPSILON))
}

/// A view sample that lands, or may land, in a texel.
#[derive(Clone, Copy)]
struct Member {
    pixel: u32,
    z: f32,
    /// Whether it lands there on this side.
    binned: bool,
    /// Whether it lands there on the GPU too (not within rounding of the texel's edges or of
    /// the map's border and depth range).
    certain: bool,
}

/// The receivers' map of the view samples `positions` (row-major, `w > 0` for a sample), with
/// what rounding may change in it.
pub fn receiver_map(positions: &[Vec4], setup: &AttySetup) -> ReceiverMap {
    let n = setup.map_size();
    let texels = (n * n) as usize;
    let size = IVec2::splat(n);
    let dc = COORD_EPSILON * n as f32;
    let mut m = ReceiverMap {
        size: n,
        near_bits: vec![NONE; texels],
        far_bits: vec![0; texels],
        near_pixel: vec![NONE; texels],
        far_pixel: vec![NONE; texels],
        alternatives: vec![[Vec::new(), Vec::new()]; texels],
        depth_uncertain: vec![false; texels],
        occupancy_uncertain: vec![false; texels],
    };
    let mut members: Vec<Vec<Member>> = vec![Vec::new(); texels];
    for (i, p) in positions.iter().enumerate() {
        if p.w <= 0.0 {
            continue;
        }
        let c = shadow_coord(setup.light_view_proj, p.xyz(), size);
        let inside = inside_map(c, size);
        let border = on_border(c, n, dc);
        if !inside && !border {
            continue;
        }
        let (t, alt) = bins(c, n, dc);
        let z = c.z.max(0.0);
        let pixel = i as u32;
        if inside {
            let k = m.index(t);
            m.near_bits[k] = m.near_bits[k].min(z.to_bits());
            m.far_bits[k] = m.far_bits[k].max(z.to_bits());
        }
        let certain = inside && !border && alt.is_empty();
        let k = m.index(t);
        members[k].push(Member {
            pixel,
            z,
            binned: inside,
            certain,
        });
        for t in alt {
            let k = m.index(t);
            members[k].push(Member {
                pixel,
                z,
                binned: false,
                certain: false,
            });
        }
    }
    // The representatives, as phase 1 picks them: the samples binned here (on this side).
    for (k, list) in members.iter().enumerate() {
        let mut near = NONE;
        let mut far = NONE;
        for s in list.iter().filter(|s| s.binned) {
            if s.z.to_bits() == m.near_bits[k] {
                near = near.min(s.pixel);
            }
            if s.z.to_bits() == m.far_bits[k] {
                far = far.min(s.pixel);
            }
        }
        m.near_pixel[k] = near;
        m.far_pixel[k] = far;
    }
    let band = 2.0 * DEPTH_EPSILON;
    for (k, list) in members.iter().enumerate() {
        // All certain: only samples within the band of an extreme may trade places. Else some
        // sample may join or leave: every sample within the band of an extreme, or beyond it if
        // it may join, and where a representative may leave, the next one.
        let certain = list.iter().all(|s| s.certain);
        if m.near_pixel[k] == NONE {
            if !certain {
                m.occupancy_uncertain[k] = true;
                m.depth_uncertain[k] = true;
                for s in list {
                    m.alternatives[k][0].push(s.pixel);
                    m.alternatives[k][1].push(s.pixel);
                }
            }
            continue;
        }
        let (near, far) = (
            f32::from_bits(m.near_bits[k]),
            f32::from_bits(m.far_bits[k]),
        );
        for s in list {
            if s.pixel != m.near_pixel[k] && s.z <= near + band {
                m.alternatives[k][0].push(s.pixel);
            }
            if s.pixel != m.far_pixel[k] && s.z >= far - band {
                m.alternatives[k][1].push(s.pixel);
            }
            if !s.certain && (s.z < near - band || s.z > far + band) {
                m.depth_uncertain[k] = true;
            }
        }
        if certain {
            continue;
        }
        let kept: Vec<&Member> = list.iter().filter(|s| s.certain).collect();
        let rep_leaves = |pixel: u32| list.iter().any(|s| s.pixel == pixel && !s.certain);
        let key = |s: &&&Member| (s.z.to_bits(), s.pixel);
        for (layer, rep) in [(0, m.near_pixel[k]), (1, m.far_pixel[k])] {
            if !rep_leaves(rep) {
                continue;
            }
            m.depth_uncertain[k] = true;
            let next = if layer == 0 {
                kept.iter().filter(|s| s.pixel != rep).min_by_key(key)
            } else {
                kept.iter()
                    .filter(|s| s.pixel != rep)
                    .max_by_key(|s| (s.z.to_bits(), u32::MAX - s.pixel))
            };
            match next {
                Some(s) => m.alternatives[k][layer].push(s.pixel),
                None => m.occupancy_uncertain[k] = true,
            }
        }
    }
    for alt in &mut m.alternatives {
        for list in alt.iter_mut() {
            list.sort_unstable();
            list.dedup();
        }
    }
    m
}
