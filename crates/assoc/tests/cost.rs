//! IoU and cosine distance against direct formulas.

use assoc::cost::{cosine_distance, cosine_distance_matrix, dot, iou, iou_matrix, validate_boxes};
use proptest::prelude::*;

fn boxes() -> impl Strategy<Value = [f64; 4]> {
    (0.0..100.0f64, 0.0..100.0f64, 0.0..50.0f64, 0.0..50.0f64)
        .prop_map(|(x, y, w, h)| [x, y, x + w, y + h])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn dot_matches_a_sum_in_f64(
        pairs in prop::collection::vec((-1.0..1.0f32, -1.0..1.0f32), 0..700)
    ) {
        let (a, b): (Vec<f32>, Vec<f32>) = pairs.into_iter().unzip();
        let want: f64 = a.iter().zip(&b).map(|(&x, &y)| f64::from(x) * f64::from(y)).sum();
        let bound: f64 = a.iter().zip(&b).map(|(&x, &y)| f64::from((x * y).abs())).sum();
        // f32 rounding: each of n additions errs by at most one ulp of the running magnitude.
        let tol = 1e-6 * bound.max(1e-30) * (a.len() as f64).max(1.0) + 1e-30;
        prop_assert!((f64::from(dot(&a, &b)) - want).abs() <= tol);
        // Extra values in the longer slice are ignored.
        let mut longer = a.clone();
        longer.push(5.0);
        prop_assert_eq!(dot(&longer, &b), dot(&a, &b));
    }

    #[test]
    fn iou_is_symmetric_bounded_and_matches_rasterised(a in boxes(), b in boxes()) {
        let v = iou(&a, &b);
        prop_assert!((0.0..=1.0).contains(&v));
        prop_assert!((v - iou(&b, &a)).abs() < 1e-12);
        // Independent check by inclusion-exclusion on the overlap rectangle.
        let ix = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
        let iy = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
        let aa = (a[2] - a[0]) * (a[3] - a[1]);
        let bb = (b[2] - b[0]) * (b[3] - b[1]);
        let u = aa + bb - ix * iy;
        let want = if u > 0.0 { ix * iy / u } else { 0.0 };
        prop_assert!((v - want).abs() < 1e-12);
    }

    #[test]
    fn cosine_distance_in_range_and_scale_invariant(
        a in prop::collection::vec(-1.0f32..1.0, 8),
        b in prop::collection::vec(-1.0f32..1.0, 8),
        s in 0.1f32..10.0,
    ) {
        let d = cosine_distance(&a, &b);
        prop_assert!((-1e-9..=2.0 + 1e-9).contains(&d));
        let scaled: Vec<f32> = a.iter().map(|x| x * s).collect();
        prop_assert!((d - cosine_distance(&scaled, &b)).abs() < 1e-5);
    }
}

#[test]
fn known_values() {
    assert_eq!(iou(&[0.0, 0.0, 2.0, 2.0], &[1.0, 0.0, 3.0, 2.0]), 2.0 / 6.0);
    assert_eq!(iou(&[0.0, 0.0, 1.0, 1.0], &[2.0, 2.0, 3.0, 3.0]), 0.0);
    assert_eq!(iou(&[1.0, 1.0, 1.0, 1.0], &[1.0, 1.0, 1.0, 1.0]), 0.0);
    assert!((cosine_distance(&[1.0, 0.0], &[0.0, 1.0]) - 1.0).abs() < 1e-12);
    assert!((cosine_distance(&[1.0, 0.0], &[-2.0, 0.0]) - 2.0).abs() < 1e-12);
    assert_eq!(cosine_distance(&[0.0, 0.0], &[1.0, 0.0]), 1.0);
    let m = iou_matrix(
        &[[0.0, 0.0, 2.0, 2.0]],
        &[[0.0, 0.0, 2.0, 2.0], [5.0, 5.0, 6.0, 6.0]],
    );
    assert_eq!(m, vec![1.0, 0.0]);
    let c = cosine_distance_matrix(&[1.0, 0.0, 0.0, 1.0], &[1.0, 1.0], 2);
    assert_eq!(c.len(), 2);
    assert!((c[0] - (1.0 - 1.0 / 2f64.sqrt())).abs() < 1e-7);
}

#[test]
fn bad_boxes_are_rejected() {
    assert!(validate_boxes(&[0.0, 0.0, 1.0]).is_err());
    assert!(validate_boxes(&[0.0, 0.0, f64::NAN, 1.0]).is_err());
    assert!(validate_boxes(&[2.0, 0.0, 1.0, 1.0]).is_err());
    assert!(validate_boxes(&[0.0, 2.0, 1.0, 1.0]).is_err());
    assert_eq!(
        validate_boxes(&[0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0]).unwrap(),
        2
    );
}
