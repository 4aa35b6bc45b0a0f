//! The view-sample pass under validation: its normals are the faces' own, even where
//! neighbouring pixels lie only a few f32 steps apart — normals from the interpolated
//! position's derivatives were noise there (tens of degrees off), and every receiver-plane and
//! tangent-plane test inherited it (`glsl/passes/view_samples.glsl`).

mod common;

use glam::Vec4Swizzles;

#[test]
fn normals_are_face_normals_where_pixels_are_denser_than_f32() {
    let engine = common::engine();
    let ctx = engine.context();
    if !ctx.info().geometry_shader {
        eprintln!("skipped: no geometryShader here, so the normals come from derivatives");
        return;
    }
    // The stress suite's dense-cell: a 1000² view of a patch 7e-4 units wide, pixels 7e-7
    // apart at |p| ~ 1.5 (f32 steps of 1.2e-7).
    let case = penumbra::stress::cases::cases()
        .into_iter()
        .find(|c| c.name == "dense-cell")
        .expect("the dense-cell case");
    let scene = (case.scene)(0, 0).expect("scene");
    let (corners, indices) = scene.merged();
    let faces: Vec<glam::Vec3> = indices
        .chunks(3)
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| corners[t[k] as usize]);
            (b - a).cross(c - a).normalize_or_zero()
        })
        .collect();
    let prepared = engine.prepare(&scene).expect("prepare");
    let positions = prepared.view.read_positions(ctx).expect("positions");
    let normals = prepared.view.read_normals(ctx).expect("normals");
    let mut checked = 0;
    for (i, (p, n)) in positions.iter().zip(&normals).enumerate().step_by(97) {
        if p.w <= 0.0 {
            continue;
        }
        let off = faces
            .iter()
            .map(|f| 1.0 - f.dot(n.xyz()).abs())
            .fold(f32::MAX, f32::min);
        assert!(
            off < 1e-5,
            "pixel {i}: normal {} is no face's ({off})",
            n.xyz()
        );
        checked += 1;
    }
    assert!(checked > 5000, "{checked} samples checked");
    common::assert_clean(&ctx.validation());
}
