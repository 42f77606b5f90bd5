//! Deferred re-identification (`reid_newborn`): a track born while an earlier one was lost takes
//! the lost track's id once its first matches agree with the lost track's appearance.
//!
//! A person who comes back from a gap away from the lost track's prediction (beyond the
//! appearance stage's gate, or at a distance the stricter `appearance_apart` refuses) is given a
//! new track. One detection is weak evidence; a few matches of the new track are a steadier
//! picture of the person. When the new track reaches `reid_newborn` matches, its gallery (the
//! mean of those first embeddings) is compared with the galleries of the confirmed tracks that
//! have been lost since before it was born. If the nearest is within the distance a match apart
//! from the prediction needs (`appearance_threshold` and `appearance_apart`) and nearer than
//! every other such lost track by [`REID_MARGIN`], the new track carries the lost track's id (and
//! its count of matches) from that frame on and the lost track ends. Ids already reported stay
//! as they were: the decision is online.

use crate::params::TrackerParams;
use crate::track::Track;

/// How much nearer in cosine distance the chosen lost track must be than every other lost track.
pub(crate) const REID_MARGIN: f64 = 0.15;

/// Applies the rule to the tracks after this frame's matches (`matched[i]`: track `i` was matched
/// this frame). Returns the number of tracks merged.
pub(crate) fn merge_newborn(tracks: &mut Vec<Track>, matched: &[bool], p: &TrackerParams) -> usize {
    if p.reid_newborn == 0 {
        return 0;
    }
    let hits = p.reid_newborn.max(p.n_init);
    let limit = p.appearance_threshold.min(p.appearance_apart);
    let mut ended = vec![false; tracks.len()];
    let mut merged = 0;
    for b in 0..tracks.len() {
        let t = &tracks[b];
        if !(matched[b] && t.confirmed && t.hits == hits && t.has_gallery()) {
            continue;
        }
        // The nearest and second nearest lost track (lost since before this one was born).
        let (mut best, mut second) = ((f64::INFINITY, usize::MAX), f64::INFINITY);
        for (a, lost) in tracks.iter().enumerate() {
            if a == b
                || ended[a]
                || matched[a]
                || !lost.confirmed
                || !lost.has_gallery()
                || lost.last_obs_frame >= t.born
            {
                continue;
            }
            let d = t.gallery_distance(lost);
            if d < best.0 {
                second = best.0;
                best = (d, a);
            } else if d < second {
                second = d;
            }
        }
        let (d, a) = best;
        if a != usize::MAX && d <= limit && d + REID_MARGIN <= second {
            ended[a] = true;
            let (id, hits) = (tracks[a].id, tracks[a].hits);
            let t = &mut tracks[b];
            t.id = id;
            t.hits += hits;
            merged += 1;
        }
    }
    if merged > 0 {
        let mut k = 0;
        tracks.retain(|_| {
            k += 1;
            !ended[k - 1]
        });
    }
    merged
}
