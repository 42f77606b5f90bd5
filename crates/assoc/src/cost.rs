//! Pairwise costs between tracks and detections: IoU, cosine distance and centre gating.
//!
//! Boxes are `[x1, y1, x2, y2]` in pixels with `x2 >= x1` and `y2 >= y1`.

/// An axis-aligned box `[x1, y1, x2, y2]`.
pub type BBox = [f64; 4];

/// Intersection over union; 0 when the union is empty (two zero-area boxes).
#[inline]
pub fn iou(a: &BBox, b: &BBox) -> f64 {
    let iw = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let ih = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = iw * ih;
    let union = area(a) + area(b) - inter;
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}

#[inline]
pub fn area(b: &BBox) -> f64 {
    (b[2] - b[0]) * (b[3] - b[1])
}

#[inline]
pub fn centre(b: &BBox) -> [f64; 2] {
    [0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3])]
}

/// Box of size `w x h` centred on `c`.
#[inline]
pub fn box_from_centre(c: [f64; 2], w: f64, h: f64) -> BBox {
    [
        c[0] - 0.5 * w,
        c[1] - 0.5 * h,
        c[0] + 0.5 * w,
        c[1] + 0.5 * h,
    ]
}

/// Row-major `a.len() x b.len()` IoU matrix.
pub fn iou_matrix(a: &[BBox], b: &[BBox]) -> Vec<f64> {
    a.iter()
        .flat_map(|x| b.iter().map(move |y| iou(x, y)))
        .collect()
}

/// `1 - a.b / (|a| |b|)`; a zero vector is treated as orthogonal to everything (distance 1).
pub fn cosine_distance(a: &[f32], b: &[f32]) -> f64 {
    let (mut dot, mut na, mut nb) = (0.0f64, 0.0f64, 0.0f64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (f64::from(x), f64::from(y));
        dot += x * y;
        na += x * x;
        nb += y * y;
    }
    if na > 0.0 && nb > 0.0 {
        1.0 - dot / (na.sqrt() * nb.sqrt())
    } else {
        1.0
    }
}

/// Row-major cosine distance matrix between `na` rows of `a` and `nb` rows of `b`, both of
/// dimension `dim` and stored row-major.
pub fn cosine_distance_matrix(a: &[f32], b: &[f32], dim: usize) -> Vec<f64> {
    if dim == 0 {
        return Vec::new();
    }
    a.chunks_exact(dim)
        .flat_map(|x| b.chunks_exact(dim).map(move |y| cosine_distance(x, y)))
        .collect()
}

/// Scales `v` to unit length in place; a zero (or non-finite norm) vector becomes all zeros, so its
/// dot product with anything is 0 (cosine distance 1).
pub fn normalise(v: &mut [f32]) {
    let norm = v
        .iter()
        .map(|&x| f64::from(x) * f64::from(x))
        .sum::<f64>()
        .sqrt();
    scale_to_unit(v, norm);
}

/// [`normalise`] applied to each row of `data` (row-major, `dim` values a row), with the same
/// result bit for bit; rows are processed four at a time, so that four sums of squares (each in
/// its own order, one dependent addition after another) advance together.
pub fn normalise_rows(data: &mut [f32], dim: usize) {
    if dim == 0 {
        return;
    }
    let mut quads = data.chunks_exact_mut(4 * dim);
    for quad in &mut quads {
        let mut norm = [0.0f64; 4];
        for k in 0..dim {
            for (r, n) in norm.iter_mut().enumerate() {
                let x = f64::from(quad[r * dim + k]);
                *n += x * x;
            }
        }
        for (row, n) in quad.chunks_exact_mut(dim).zip(norm) {
            scale_to_unit(row, n.sqrt());
        }
    }
    quads
        .into_remainder()
        .chunks_exact_mut(dim)
        .for_each(normalise);
}

/// Divides `v` by `norm` (its length); all zeros where the norm is zero or not finite.
#[inline]
fn scale_to_unit(v: &mut [f32], norm: f64) {
    if norm > 0.0 && norm.is_finite() {
        let inv = (1.0 / norm) as f32;
        v.iter_mut().for_each(|x| *x *= inv);
    } else {
        v.fill(0.0);
    }
}

/// Independent partial sums in [`dot`]: enough for the compiler to fill the vector registers
/// (one sequential sum is bound by the latency of each addition).
const DOT_LANES: usize = 32;

/// Dot product accumulated in f32 over [`DOT_LANES`] partial sums, which the compiler turns
/// into vector instructions; the lengths must agree (extra values of the longer slice are
/// ignored).
#[inline]
pub fn dot(a: &[f32], b: &[f32]) -> f32 {
    dot_lanes(a, b)
}

/// The largest [`dot`] of `e` with the rows of `rows` (row-major, `e.len()` values each);
/// `-inf` for no rows. The gallery hot loop: where the CPU has AVX the same partial sums run in
/// 256-bit registers, with the same result bit for bit (each lane adds the same products in the
/// same order).
pub fn max_dot(rows: &[f32], e: &[f32]) -> f32 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX (checked just above), all `max_dot_avx` requires.
        return unsafe { max_dot_avx(rows, e) };
    }
    max_dot_lanes(rows, e)
}

/// [`max_dot_lanes`] in 256-bit registers: the [`DOT_LANES`] partial sums are four vectors, each
/// lane adding the same products in the same order (a multiply, then an add: no fused
/// multiply-add, which would round differently), then reduced in [`reduce_lanes`]'s tree.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn max_dot_avx(rows: &[f32], e: &[f32]) -> f32 {
    use std::arch::x86_64::{
        __m256, _mm256_add_ps, _mm256_castps256_ps128, _mm256_extractf128_ps, _mm256_loadu_ps,
        _mm256_mul_ps, _mm256_setzero_ps, _mm_add_ps, _mm_add_ss, _mm_cvtss_f32, _mm_movehl_ps,
        _mm_shuffle_ps,
    };
    const _: () = assert!(DOT_LANES == 32, "four vectors of eight lanes");
    let d = e.len();
    if d == 0 {
        return f32::NEG_INFINITY;
    }
    let full = d - d % DOT_LANES;
    let mut best = f32::NEG_INFINITY;
    for g in rows.chunks_exact(d) {
        let mut acc: [__m256; 4] = [_mm256_setzero_ps(); 4];
        let mut k = 0;
        while k < full {
            // SAFETY: k + 32 <= full <= d = g.len() = e.len(), so every load is in bounds.
            unsafe {
                for (v, a) in acc.iter_mut().enumerate() {
                    let x = _mm256_loadu_ps(g.as_ptr().add(k + 8 * v));
                    let y = _mm256_loadu_ps(e.as_ptr().add(k + 8 * v));
                    *a = _mm256_add_ps(*a, _mm256_mul_ps(x, y));
                }
            }
            k += DOT_LANES;
        }
        // The tree of `reduce_lanes`: lanes k, k + 8, k + 16, k + 24, then halves.
        let s = _mm256_add_ps(_mm256_add_ps(acc[0], acc[1]), _mm256_add_ps(acc[2], acc[3]));
        let t = _mm_add_ps(_mm256_castps256_ps128(s), _mm256_extractf128_ps::<1>(s));
        let u = _mm_add_ps(t, _mm_movehl_ps(t, t));
        let sum = _mm_cvtss_f32(_mm_add_ss(u, _mm_shuffle_ps::<0b01>(u, u)));
        let tail: f32 = g[full..].iter().zip(&e[full..]).map(|(x, y)| x * y).sum();
        best = best.max(sum + tail);
    }
    best
}

/// Sums the [`DOT_LANES`] partial sums as a tree (lanes `k`, `k + 8`, `k + 16` and `k + 24`
/// first, then halves of eight, four and two): short dependency chains, and the order in which
/// vector registers reduce.
#[inline(always)]
fn reduce_lanes(acc: &[f32; DOT_LANES]) -> f32 {
    let s: [f32; 8] = std::array::from_fn(|k| (acc[k] + acc[k + 8]) + (acc[k + 16] + acc[k + 24]));
    let t: [f32; 4] = std::array::from_fn(|k| s[k] + s[k + 4]);
    (t[0] + t[2]) + (t[1] + t[3])
}

#[inline(always)]
fn max_dot_lanes(rows: &[f32], e: &[f32]) -> f32 {
    if e.is_empty() {
        return f32::NEG_INFINITY;
    }
    rows.chunks_exact(e.len())
        .map(|g| dot_lanes(g, e))
        .fold(f32::NEG_INFINITY, f32::max)
}

#[inline(always)]
fn dot_lanes(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f32; DOT_LANES];
    let (xs, ys) = (a.chunks_exact(DOT_LANES), b.chunks_exact(DOT_LANES));
    let tail: f32 = xs
        .remainder()
        .iter()
        .zip(ys.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in xs.zip(ys) {
        // Fixed-size arrays: no bounds checks in the loop, so it becomes vector code.
        let x: &[f32; DOT_LANES] = x.try_into().expect("chunk of DOT_LANES");
        let y: &[f32; DOT_LANES] = y.try_into().expect("chunk of DOT_LANES");
        for k in 0..DOT_LANES {
            acc[k] += x[k] * y[k];
        }
    }
    reduce_lanes(&acc) + tail
}

/// Largest coordinate magnitude a box may have: squares of coordinates (areas, squared
/// distances) and their sums then stay finite, so overlaps and distances are computed exactly
/// enough to track (at 1e154 and beyond, areas overflow to infinity).
pub const MAX_COORDINATE: f64 = 1e150;

/// Most detections one tracker frame takes. Far above any crowd a camera frame holds, it bounds
/// the work and memory of a frame whose detections all overlap (the gated pairs grow with
/// tracks x detections): such a frame is refused with one clear error instead.
pub const MAX_DETECTIONS_PER_FRAME: usize = 2000;

/// Checks a flat `[x1, y1, x2, y2]*` array: finite, within [`MAX_COORDINATE`], not inverted.
/// Returns the number of boxes.
pub fn validate_boxes(flat: &[f64]) -> Result<usize, crate::TrackError> {
    use crate::TrackError::InvalidInput;
    if flat.len() % 4 != 0 {
        return Err(InvalidInput(format!(
            "boxes must have 4 values each (x1, y1, x2, y2); got {} values",
            flat.len()
        )));
    }
    for (k, b) in flat.chunks_exact(4).enumerate() {
        if b.iter().any(|x| !x.is_finite()) {
            return Err(InvalidInput(format!("box {k} is not finite: {b:?}")));
        }
        if b.iter().any(|x| x.abs() > MAX_COORDINATE) {
            return Err(InvalidInput(format!(
                "box {k} has a coordinate beyond {MAX_COORDINATE:e} in magnitude: {b:?}"
            )));
        }
        if b[2] < b[0] || b[3] < b[1] {
            return Err(InvalidInput(format!(
                "box {k} is inverted (x2 < x1 or y2 < y1): {b:?}"
            )));
        }
    }
    Ok(flat.len() / 4)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalise_rows_is_normalise_on_each_row_bit_for_bit() {
        let mut x = 0x1234_5678_9abc_def1u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 20) as f32 - 8.0
        };
        for dim in [1, 3, 512] {
            for rows in [0, 1, 4, 7, 9] {
                let mut data: Vec<f32> = (0..dim * rows).map(|_| next()).collect();
                if rows > 2 {
                    data[2 * dim..3 * dim].fill(0.0); // a zero row stays zero
                }
                let mut want = data.clone();
                want.chunks_exact_mut(dim).for_each(normalise);
                normalise_rows(&mut data, dim);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&data), bits(&want), "dim {dim}, rows {rows}");
            }
        }
    }

    #[test]
    fn max_dot_is_the_largest_dot_bit_for_bit_with_and_without_avx() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        };
        for n in [1, 15, 16, 17, 100, 512, 515] {
            for rows in [0, 1, 3, 8] {
                let g: Vec<f32> = (0..n * rows).map(|_| next()).collect();
                let e: Vec<f32> = (0..n).map(|_| next()).collect();
                let want = g
                    .chunks_exact(n)
                    .map(|r| dot(r, &e))
                    .fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(
                    max_dot(&g, &e).to_bits(),
                    want.to_bits(),
                    "n {n}, rows {rows}"
                );
                assert_eq!(max_dot_lanes(&g, &e).to_bits(), want.to_bits());
            }
        }
    }
}
