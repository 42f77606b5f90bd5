//! The score cuts of one frame, read from the scores the tracker has seen, so that one set of
//! thresholds serves detectors whose scores differ in range and shape (an unbounded detector
//! score mapped into `[0, 1]`, a file already cut at 0.5, a quantised network's shifted scores).
//! The thresholds are compared with the scores as given, with two guards (the score calibration
//! block):
//!
//! `score_quantile_floor` (a fraction `q`, 0: off) keeps the lowest scores of the window out of
//! the matching stages and births: after warm-up, `det_threshold` and `new_track_threshold` are
//! raised to at least the `q`-quantile of the last `window` scores.
//!
//! `score_quantile_ceiling` (a fraction `c`, 0: off) keeps a detector whose scores sit below the
//! cuts from being ignored: where the `c`-quantile of the last `window` scores (before warm-up:
//! the highest score seen) is below `det_threshold`, that cut is lowered to at most this quantile
//! and to at most its ratio reading `lo + t * (hi - lo)`, `hi` the highest score seen and `lo`
//! the lowest one or 0, whichever is lower, and `low_threshold` to at most its ratio reading;
//! `new_track_threshold` likewise, compared with the same quantile. The ratio reading undoes a
//! detector whose scores are today's multiplied by a constant; the quantile bounds any other
//! monotone squeeze. A detector whose cuts reject fewer than a fraction `c` of its scores is
//! read as before. The quantile floor applies after the ceiling.
//!
//! The tracker reads its cuts once per frame, after observing that frame's scores, and compares
//! the raw scores with them (a score passes a cut when `score >= cut`).

use std::collections::VecDeque;

/// How the score thresholds are read: the `score_*` parameters of the tracker.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScoreReading {
    /// Scores (the last ones seen) whose quantiles are read.
    pub window: usize,
    /// Scores to see before quantiles are used.
    pub warm_up: usize,
    /// `score_quantile_floor` (0: off).
    pub quantile_floor: f64,
    /// `score_quantile_ceiling` (0: off).
    pub quantile_ceiling: f64,
}

/// The three score thresholds: as the caller gives them, or as raw cuts of one frame
/// ([`ScoreScaler::cuts`]). A score passes a cut when `score >= cut`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScoreCuts {
    /// Detections from here take part in every matching stage (`det_threshold`).
    pub det: f64,
    /// Detections from here (and from `det`) may start a track (`new_track_threshold`).
    pub new_track: f64,
    /// The lowest score of the second pass (`low_threshold`).
    pub low: f64,
}

/// The scores seen so far: their count, lowest and highest, and the last `window` of them.
#[derive(Clone, Debug)]
pub struct ScoreScaler {
    seen: usize,
    lo: f64,
    hi: f64,
    /// The last scores in arrival order, and the same scores sorted.
    recent: VecDeque<f64>,
    sorted: Vec<f64>,
    /// The last frame's confident cut (see [`ScoreScaler::confident_cut`]).
    confident_cut: f64,
}

impl Default for ScoreScaler {
    fn default() -> Self {
        Self::new()
    }
}

impl ScoreScaler {
    pub fn new() -> Self {
        Self {
            seen: 0,
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            recent: VecDeque::new(),
            sorted: Vec::new(),
            confident_cut: f64::NEG_INFINITY,
        }
    }

    /// Forgets every score seen.
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Scores seen since creation or the last reset.
    pub fn seen(&self) -> usize {
        self.seen
    }

    /// Records one frame's scores (NaN is not expected: the tracker rejects it first); only the
    /// last `window` are kept for the quantiles.
    pub fn observe(&mut self, scores: &[f64], window: usize) {
        for &s in scores {
            self.seen += 1;
            self.lo = self.lo.min(s);
            self.hi = self.hi.max(s);
            self.recent.push_back(s);
            let at = self.sorted.partition_point(|&x| x < s);
            self.sorted.insert(at, s);
        }
        while self.recent.len() > window.max(1) {
            let old = self.recent.pop_front().expect("non-empty");
            let at = self.sorted.partition_point(|&x| x < old);
            self.sorted.remove(at);
        }
    }

    /// The score from which a detection of the last [`ScoreScaler::cuts`] call was confident
    /// by the cuts as `score_quantile_ceiling` reads them, before
    /// `score_quantile_floor` raised them: the larger of `det_threshold` and
    /// `new_track_threshold` there.
    pub fn confident_cut(&self) -> f64 {
        self.confident_cut
    }

    /// Whether the detector thresholds its own output: every score seen so far is at or above
    /// [`ScoreScaler::confident_cut`] (a `det-frcnn.txt` cut at 0.5 by its publisher).
    pub fn thresholded(&self) -> bool {
        self.lo >= self.confident_cut
    }

    /// The `t`-quantile of the last scores kept: the smallest of them with at least a fraction
    /// `t` of them at or below it (`-inf` for `t <= 0` or when none is kept, `inf` for `t > 1`).
    pub fn quantile(&self, t: f64) -> f64 {
        let n = self.sorted.len();
        if t <= 0.0 || n == 0 {
            return f64::NEG_INFINITY;
        }
        if t > 1.0 {
            return f64::INFINITY;
        }
        // Smallest k with (k + 1) / n >= t (t * n first, then fixed up exactly).
        let frac = |k: usize| (k + 1) as f64 / n as f64;
        let mut k = ((t * n as f64).ceil() as usize).clamp(1, n) - 1;
        while k > 0 && frac(k - 1) >= t {
            k -= 1;
        }
        while k + 1 < n && frac(k) < t {
            k += 1;
        }
        self.sorted[k]
    }

    /// Threshold `t` read as a place between the detector's floor (the lowest score seen, or 0
    /// where that is higher) and the highest score seen (`t` itself where that range is empty).
    pub fn ratio_cut(&self, t: f64) -> f64 {
        let lo = self.lo.min(0.0);
        if self.seen > 0 && self.hi > lo && (self.hi - lo).is_finite() && t.is_finite() {
            lo + t * (self.hi - lo)
        } else {
            t
        }
    }

    /// Observes one frame's scores, then returns the raw cuts that the thresholds `given` stand
    /// for under `reading` (see the module doc).
    pub fn cuts(&mut self, reading: &ScoreReading, given: ScoreCuts, scores: &[f64]) -> ScoreCuts {
        self.observe(scores, reading.window);
        let mut c = given;
        if reading.quantile_ceiling > 0.0 && self.seen > 0 {
            let q = if self.seen >= reading.warm_up {
                self.quantile(reading.quantile_ceiling)
            } else {
                self.hi
            };
            let starved = q < c.det;
            if starved {
                c.det = c.det.min(q).min(self.ratio_cut(given.det));
            }
            if q < c.new_track {
                c.new_track = c.new_track.min(q).min(self.ratio_cut(given.new_track));
            }
            if starved {
                c.low = c.low.min(self.ratio_cut(given.low));
            }
        }
        self.confident_cut = c.det.max(c.new_track);
        if reading.quantile_floor > 0.0 && self.seen >= reading.warm_up {
            let q = self.quantile(reading.quantile_floor);
            c.det = c.det.max(q);
            c.new_track = c.new_track.max(q);
        }
        c
    }
}
