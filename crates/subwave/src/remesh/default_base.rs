//! The base-face search of `subwave remesh` when no base size is given: remeshes over more
//! base faces where the one over the default misses part of the input or leaves folds.
//!
//! MAPS (Lee et al. 1998, §3) builds its base domain by simplification, and a base face
//! larger than a thin part of the input either cuts the part off (the remesh *misses* it:
//! the cow's tail at 200 base faces) or folds the remesh across it (the welded teapot's
//! spout lip, suzanne, the cow at 5 levels). Both go with a finer base. This module holds the
//! policy, as a function of what each remesh showed; the caller does the remeshing (with its
//! progress display, re-sampling and distance measure) in a closure.
//!
//! Policy, from the default base faces:
//! - a remesh that misses part of the input is redone over [`finer_base`] base faces (twice
//!   as many, up to [`MAX_DEFAULT_BASE_FACES`]), and is never kept
//!   while a finer base remains;
//! - one that leaves flipped or degenerate faces is redone over [`finer_base_for_folds`]
//!   base faces (twice as many, past [`MAX_DEFAULT_BASE_FACES`] while the finest level keeps
//!   at most [`MAX_FOLD_FACES`] faces and the base no more than the input's triangles) while
//!   the best so far leaves any, and the last try left strictly fewer or the next try's
//!   finest level keeps at most [`MAX_FOLD_FACES`] faces (folds do not fall steadily with
//!   the base faces: the beetle at 3 levels leaves 4, 6, 5 and none over 200, 400, 800 and
//!   1,600); the one with the fewest is kept (the first of equals).
//!
//! The codec's [`crate::codec::prepare`] takes the same base steps for a remesh that misses
//! part of the input (then one level finer), and does not retry folds: it repairs the folds
//! of its normal re-sampling in place.

/// Default base faces of the remesh of an irregular input.
pub const DEFAULT_BASE_FACES: usize = 200;

/// Most base faces asked of a remesh redone over more than the default
/// ([`DEFAULT_BASE_FACES`]): four times as many.
///
/// A thin part that the base mesh cuts off (the simplification pays little to shorten it)
/// comes back with a finer base at half the vertices of a finer level. The cow (2,903
/// vertices; 2026-12-05, normal remesh, `subwave eval`, Draco at compression level 10 beside
/// it): over 200 base faces it misses its tail at 3 and 4 levels, and 5 levels (102,402
/// vertices) code to 82 KB in 8.8 s, topping out at 70.3 dB, at 1.48× Draco's bytes at
/// 66.8 dB, 2.27× at 68.8, 3.60× at 70.0; over 400 base faces 3 levels still miss (3.5%),
/// over 800 they do not (0.99%): 25,602 vertices, 34 KB (2.9 s with the two remeshes that
/// missed), topping out at 75.8 dB, at 1.24× Draco at 66.0 dB, 1.52× at 68.7, 1.92× at 70.8
/// (since [`crate::codec::prepare::CEILING_DB`], raised to 4 levels over 800: 102,402
/// vertices, topping out at 83.3 dB).
pub const MAX_DEFAULT_BASE_FACES: usize = 4 * DEFAULT_BASE_FACES;

/// The base faces to try after a remesh over `base_faces` (default ones) missed part of the
/// input or left folds: twice as many, up to [`MAX_DEFAULT_BASE_FACES`]; `None` once there.
pub fn finer_base(base_faces: usize) -> Option<usize> {
    (base_faces < MAX_DEFAULT_BASE_FACES).then(|| (2 * base_faces).min(MAX_DEFAULT_BASE_FACES))
}

/// Most faces of the finest level of a remesh redone for its folds over more than
/// [`MAX_DEFAULT_BASE_FACES`] base faces (2^18, the codec's
/// [`crate::codec::prepare::MAX_RAISED_FACES`]).
///
/// The cow at 3 levels (5,804 input faces, `remesh --repair`, 2026-12-05): over 800 base faces
/// 5 flipped faces (73.7 dB), over 1,600 one (79.9 dB), over 3,200 none (86.4 dB, 204,800
/// faces); each try takes 1.5–2 s. At 5 levels even 800 base faces make 819,200 faces, so
/// the search ends there as before.
pub const MAX_FOLD_FACES: usize = 1 << 18;

/// Most base faces a remesh redone for its folds is asked: sixteen times the default (a base
/// mesh is a simplification of the input; the cow has 5,804 faces).
pub const MAX_FOLD_BASE_FACES: usize = 16 * DEFAULT_BASE_FACES;

/// The base faces to try after a remesh over `base_faces` at `levels` of an input of
/// `input_faces` triangles left folds: [`finer_base`], then past [`MAX_DEFAULT_BASE_FACES`]
/// twice as many, up to [`MAX_FOLD_BASE_FACES`] and to `input_faces` (a base mesh simplifies
/// the input: the beetle's 2,053 triangles stop it at 1,600, where asking 3,200 had given a
/// base of 2,015), while the finest level keeps at most [`MAX_FOLD_FACES`] faces; `None`
/// after.
pub fn finer_base_for_folds(base_faces: usize, levels: u32, input_faces: usize) -> Option<usize> {
    finer_base(base_faces).or_else(|| {
        let b = 2 * base_faces;
        if b > MAX_FOLD_BASE_FACES || b > input_faces {
            return None;
        }
        (fold_faces(b, levels)? <= MAX_FOLD_FACES).then_some(b)
    })
}

/// Faces of the finest level of a triangle remesh over `base_faces` at `levels` (`None` past
/// `usize`).
fn fold_faces(base_faces: usize, levels: u32) -> Option<usize> {
    4usize
        .checked_pow(levels)
        .and_then(|n| n.checked_mul(base_faces))
}

/// A remesh that missed part of the input before the one kept (JSON keys `base_faces`,
/// `levels`): by [`crate::codec::prepare::MISS_FRACTION`] in the codec, by the caller's
/// test ([`Outcome::misses`]) in [`search`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Missed {
    /// The base faces asked of it.
    pub base_faces: usize,
    /// Its levels.
    pub levels: u32,
}

/// What a remesh over some base faces showed ([`search`] decides from it).
pub trait Outcome {
    /// Faces flipped against the input.
    fn flipped(&self) -> usize;
    /// Degenerate faces.
    fn degenerate(&self) -> usize;
    /// Whether it misses part of the input (the caller's distance test).
    fn misses(&self) -> bool;
}

/// A remesh over the default base faces, or over a finer base after it, that left flipped
/// or degenerate faces and was not kept (JSON keys `base_faces`, `levels`, `flipped`,
/// `degenerate`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Refolded {
    /// The base faces asked of it.
    pub base_faces: usize,
    /// Its levels.
    pub levels: u32,
    /// Its flipped faces.
    pub flipped: usize,
    /// Its degenerate faces.
    pub degenerate: usize,
}

/// The outcome [`search`] kept and how it got there.
#[derive(Debug)]
pub struct Searched<O> {
    /// The remesh kept.
    pub kept: O,
    /// The base faces asked of it.
    pub base_faces: usize,
    /// The remeshes that missed part of the input, in order.
    pub missed: Vec<Missed>,
    /// The remeshes that left more flipped or degenerate faces than the one kept (or as many,
    /// over more base faces), by base faces.
    pub refolded: Vec<Refolded>,
}

/// Remeshes with `attempt(base_faces)` from `base_faces`, by the policy of the module
/// documentation when `searching` (no base size was given), else once. `levels` are the
/// remeshes' levels and `input_faces` the input's triangles (both bound the base faces tried
/// for folds; the levels label the records).
///
/// # Errors
/// The first error of `attempt` (any error type: the caller's).
pub fn search<O: Outcome, E>(
    base_faces: usize,
    levels: u32,
    input_faces: usize,
    searching: bool,
    mut attempt: impl FnMut(usize) -> Result<O, E>,
) -> Result<Searched<O>, E> {
    let folds = |o: &O| o.flipped() + o.degenerate();
    let record = |o: &O, base_faces: usize| Refolded {
        base_faces,
        levels,
        flipped: o.flipped(),
        degenerate: o.degenerate(),
    };
    let mut base = base_faces;
    let mut missed = Vec::new();
    let mut refolded = Vec::new();
    // The remesh with the fewest folds so far (of those that do not miss), and its base.
    let mut best: Option<(O, usize)> = None;
    loop {
        let o = attempt(base)?;
        let finer = finer_base(base).filter(|_| searching);
        if o.misses() {
            if let Some(b) = finer {
                missed.push(Missed {
                    base_faces: base,
                    levels,
                });
                base = b;
                continue;
            }
        }
        if !searching || (folds(&o) == 0 && best.is_none()) {
            return Ok(Searched {
                kept: o,
                base_faces: base,
                missed,
                refolded,
            });
        }
        let next = finer_base_for_folds(base, levels, input_faces);
        // Whether this remesh leaves fewer folds than the best so far (kept: the first of
        // equals).
        let improved = match &best {
            Some((b, _)) => folds(&o) < folds(b),
            None => true,
        };
        if improved {
            if let Some((b, b_base)) = best.take() {
                refolded.push(record(&b, b_base));
            }
            best = Some((o, base));
        } else {
            refolded.push(record(&o, base));
        }
        let (kept, kept_base) = best.take().expect("set above");
        // Folds do not fall steadily with the base faces (the beetle at 3 levels: 4, 6, 5 and
        // none over 200, 400, 800 and 1,600): past a try that left no fewer, the search goes
        // on while the next finest level keeps at most MAX_FOLD_FACES faces.
        let go_on = |b: &usize| {
            folds(&kept) > 0
                && (improved || fold_faces(*b, levels).is_some_and(|n| n <= MAX_FOLD_FACES))
        };
        match next.filter(go_on) {
            Some(b) => {
                best = Some((kept, kept_base));
                base = b;
            }
            None => {
                refolded.sort_by_key(|r| r.base_faces);
                return Ok(Searched {
                    kept,
                    base_faces: kept_base,
                    missed,
                    refolded,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fake remesh: (flipped, degenerate, misses).
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Fake(usize, usize, bool);

    impl Outcome for Fake {
        fn flipped(&self) -> usize {
            self.0
        }
        fn degenerate(&self) -> usize {
            self.1
        }
        fn misses(&self) -> bool {
            self.2
        }
    }

    /// Runs [`search`] over outcomes given per base size; returns the kept base, the bases
    /// tried, and the records.
    fn run(searching: bool, by_base: &[(usize, Fake)]) -> (usize, Vec<usize>, Searched<Fake>) {
        run_levels(3, searching, by_base)
    }

    /// [`run`] at `levels`.
    fn run_levels(
        levels: u32,
        searching: bool,
        by_base: &[(usize, Fake)],
    ) -> (usize, Vec<usize>, Searched<Fake>) {
        let mut tried = Vec::new();
        let s = search(200, levels, 6000, searching, |b| {
            tried.push(b);
            Ok::<_, ()>(by_base.iter().find(|x| x.0 == b).expect("base asked").1)
        })
        .unwrap();
        (s.base_faces, tried, s)
    }

    #[test]
    fn clean_remeshes_are_kept() {
        let (base, tried, s) = run(true, &[(200, Fake(0, 0, false))]);
        assert_eq!((base, tried), (200, vec![200]));
        assert!(s.missed.is_empty() && s.refolded.is_empty());
    }

    #[test]
    fn folds_are_remeshed_finer_while_that_leaves_fewer() {
        // Teapot at 3 levels: 5 flipped over 200, none over 400.
        let (base, tried, s) = run(true, &[(200, Fake(5, 0, false)), (400, Fake(0, 0, false))]);
        assert_eq!((base, tried), (400, vec![200, 400]));
        assert_eq!(
            s.refolded,
            [Refolded {
                base_faces: 200,
                levels: 3,
                flipped: 5,
                degenerate: 0
            }]
        );
        // Cow at 5 levels: 18, 1, 0.
        let (base, tried, s) = run(
            true,
            &[
                (200, Fake(18, 0, false)),
                (400, Fake(1, 0, false)),
                (800, Fake(0, 0, false)),
            ],
        );
        assert_eq!((base, tried), (800, vec![200, 400, 800]));
        let bases: Vec<usize> = s.refolded.iter().map(|r| r.base_faces).collect();
        assert_eq!(bases, [200, 400]);
        // Beetle at 3 levels: 4, 6, 5 and none over 200, 400, 800 and 1,600. Past the tries
        // that leave no fewer, the search goes on while the finest level stays small.
        let beetle = [
            (200, Fake(4, 0, false)),
            (400, Fake(6, 0, false)),
            (800, Fake(5, 0, false)),
            (1600, Fake(0, 0, false)),
        ];
        let (base, tried, s) = run(true, &beetle);
        assert_eq!((base, tried), (1600, vec![200, 400, 800, 1600]));
        assert_eq!(s.kept, Fake(0, 0, false));
        let bases: Vec<usize> = s.refolded.iter().map(|r| r.base_faces).collect();
        assert_eq!(bases, [200, 400, 800]);
        // At 5 levels 800 base faces would make 819,200: after 400 left no fewer, the 200
        // is kept.
        let (base, tried, s) = run_levels(5, true, &beetle);
        assert_eq!((base, tried), (200, vec![200, 400]));
        assert_eq!(s.kept, Fake(4, 0, false));
        assert_eq!(s.refolded[0].base_faces, 400);
        // At 3 levels the ladder ends at 3,200 base faces: the fewest is kept, the first of
        // equals.
        let (base, tried, s) = run(
            true,
            &[
                (200, Fake(3, 0, false)),
                (400, Fake(2, 0, false)),
                (800, Fake(4, 0, false)),
                (1600, Fake(1, 1, false)),
                (3200, Fake(5, 0, false)),
            ],
        );
        assert_eq!((base, tried), (400, vec![200, 400, 800, 1600, 3200]));
        assert_eq!(s.kept, Fake(2, 0, false));
        assert_eq!(s.refolded.len(), 4);
        // Past the largest default base while the finest level stays small: 3 levels over
        // 3,200 base faces make 204,800 faces, over 6,400 too many.
        let steps = [
            (200, Fake(9, 0, false)),
            (400, Fake(7, 0, false)),
            (800, Fake(5, 0, false)),
            (1600, Fake(2, 0, false)),
            (3200, Fake(1, 0, false)),
        ];
        let (base, tried, _) = run(true, &steps);
        assert_eq!((base, tried), (3200, vec![200, 400, 800, 1600, 3200]));
        // At 5 levels the largest default base is the last.
        let (base, tried, _) = run_levels(5, true, &steps);
        assert_eq!((base, tried), (800, vec![200, 400, 800]));
        assert_eq!(finer_base_for_folds(800, 5, 6000), None);
        assert_eq!(finer_base_for_folds(800, 3, 6000), Some(1600));
        assert_eq!(finer_base_for_folds(3200, 3, 6000), None);
        assert_eq!(finer_base_for_folds(200, 20, 6000), Some(400));
        assert_eq!(finer_base_for_folds(800, 40, 6000), None);
        // Never past sixteen times the default base, even at few levels, nor past the
        // input's triangles.
        assert_eq!(finer_base_for_folds(1600, 1, 6000), Some(3200));
        assert_eq!(finer_base_for_folds(3200, 1, 100_000), None);
        assert_eq!(finer_base_for_folds(800, 3, 2053), Some(1600));
        assert_eq!(finer_base_for_folds(1600, 3, 2053), None);
    }

    #[test]
    fn misses_go_finer_before_folds_count() {
        // Cow at 3 levels: misses over 200 and 400, then 5, 1 and 0 flipped over 800, 1,600
        // and 3,200.
        let (base, tried, s) = run(
            true,
            &[
                (200, Fake(0, 0, true)),
                (400, Fake(0, 0, true)),
                (800, Fake(5, 0, false)),
                (1600, Fake(1, 0, false)),
                (3200, Fake(0, 0, false)),
            ],
        );
        assert_eq!((base, tried), (3200, vec![200, 400, 800, 1600, 3200]));
        assert_eq!(s.missed.len(), 2);
        let bases: Vec<usize> = s.refolded.iter().map(|r| r.base_faces).collect();
        assert_eq!(bases, [800, 1600]);
        // A remesh that misses is not kept as the best of the folds.
        let (base, _, s) = run(
            true,
            &[
                (200, Fake(3, 0, false)),
                (400, Fake(0, 0, true)),
                (800, Fake(1, 0, false)),
                (1600, Fake(1, 0, false)),
                (3200, Fake(2, 0, false)),
            ],
        );
        assert_eq!(base, 800);
        assert_eq!(s.missed[0].base_faces, 400);
        assert_eq!(s.refolded[0].base_faces, 200);
    }

    #[test]
    fn a_given_base_is_kept() {
        let (base, tried, s) = run(false, &[(200, Fake(5, 1, true))]);
        assert_eq!((base, tried), (200, vec![200]));
        assert!(s.missed.is_empty() && s.refolded.is_empty());
    }
}
