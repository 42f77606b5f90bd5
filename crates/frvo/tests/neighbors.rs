//! The neighbour grid against brute force.

use frvo::geometry::V2;
use frvo::neighbors::NeighborGrid;
use proptest::prelude::*;

/// Checks every agent's query (valid or not) against brute force: the valid agents other
/// than it strictly within the radius, nearest first, ties by index, at most `max`.
fn check(positions: &[V2], valid: &[bool], radius: f64, max: usize) -> Result<(), TestCaseError> {
    let mut grid = NeighborGrid::default();
    grid.build(positions, valid, radius);
    let mut out = Vec::new();
    for me in 0..positions.len() {
        grid.query(positions, me, max, &mut out);
        let mut want: Vec<(f64, usize)> = (0..positions.len())
            .filter(|&j| j != me && valid[j] && radius > 0.0)
            .map(|j| ((positions[j] - positions[me]).norm_squared(), j))
            .filter(|&(d2, _)| d2 < radius * radius)
            .collect();
        want.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        want.truncate(max);
        prop_assert_eq!(&out, &want, "agent {}", me);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, failure_persistence: None, ..ProptestConfig::default() })]

    /// The grid's answer is the brute-force one.
    #[test]
    fn query_matches_brute_force(
        pts in prop::collection::vec((0.0f64..300.0, 0.0f64..300.0), 1..120),
        radius in 0.0f64..200.0,
        max in 0usize..60,
        snap in any::<bool>(),
    ) {
        // Snapped to a 10 px lattice, many distances tie exactly.
        let positions: Vec<V2> = pts.iter().map(|&(x, y)| {
            if snap { V2::new((x / 10.0).round() * 10.0, (y / 10.0).round() * 10.0) } else { V2::new(x, y) }
        }).collect();
        check(&positions, &vec![true; positions.len()], radius, max)?;
    }

    /// Also in clusters far apart, where the cells sized by the whole crowd are far too
    /// large for a cluster, with invalid agents.
    #[test]
    fn query_matches_brute_force_in_clusters(
        clusters in prop::collection::vec(
            ((-1e4f64..1e4, -1e4f64..1e4), 0.0f64..100.0, prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 1..60)),
            1..4,
        ),
        valid in prop::collection::vec(prop::bool::weighted(0.9), 240),
        log_radius in 0.0f64..4.5,
        max in 0usize..80,
    ) {
        let positions: Vec<V2> = clusters.iter().flat_map(|&((cx, cy), spread, ref pts)| {
            pts.iter().map(move |&(x, y)| V2::new(cx + spread * x, cy + spread * y))
        }).collect();
        check(&positions, &valid[..positions.len()], 10f64.powf(log_radius), max)?;
    }
}

#[test]
fn coincident_agents_and_odd_radii() {
    let positions = vec![V2::new(5.0, -3.0); 40];
    let valid = vec![true; 40];
    for radius in [0.0, -1.0, f64::NAN, 1e-300, 1.0, f64::INFINITY] {
        for max in [0, 1, 10, 39, 100] {
            check(&positions, &valid, radius, max).unwrap();
        }
    }
}

#[test]
fn huge_coordinates() {
    let positions = vec![
        V2::new(1e300, -1e300),
        V2::new(-1e300, 1e300),
        V2::new(f64::MAX, 0.0),
        V2::new(0.0, 0.0),
        V2::new(1.0, 1.0),
        V2::new(1e6, 1e6),
    ];
    let valid = vec![true; positions.len()];
    for radius in [1.0, 10.0, 1e7, f64::INFINITY] {
        for max in [1, 3, 10] {
            check(&positions, &valid, radius, max).unwrap();
        }
    }
}

/// Many agents within the radius, more or fewer than `max`, in a crowd whose cells are
/// sized by one far-away agent.
#[test]
fn crowded_discs() {
    // A dense 20 x 20 lattice, and one agent far away that makes the crowd look sparse.
    let mut positions: Vec<V2> = (0..400)
        .map(|i| V2::new((i % 20) as f64, (i / 20) as f64))
        .collect();
    positions.push(V2::new(1e5, 1e5));
    let valid = vec![true; positions.len()];
    for max in [1, 5, 254, 255, 256, 300, usize::MAX] {
        check(&positions, &valid, 1e6, max).unwrap();
        check(&positions[..400], &valid[..400], 12.0, max).unwrap();
    }
    // A 20 x 5 block of it: the first disc holds all 100.
    let mut block = positions[..100].to_vec();
    block.push(positions[400]);
    for max in [1, 5, 50, 99, 100, 200] {
        check(&block, &valid[..block.len()], 1e6, max).unwrap();
    }
}
