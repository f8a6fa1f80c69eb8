use super::*;
use proptest::prelude::*;

/// A made-up CV error (rms, its standard error).
fn cv(e: f64, se: f64) -> CvError {
    CvError { e, se }
}

/// Absolute tolerance on the Šidák level's round trip through `powf`.
const SIDAK_TOL: f64 = 1e-12;

/// One fold of `kinds` rows with nominal errors `nominal` and the candidate's `model`.
fn fold<'a>(name: &str, kinds: Vec<&'a str>, nominal: Vec<f64>, model: Vec<f64>) -> FoldRows<'a> {
    FoldRows {
        name: name.into(),
        kinds,
        nominal_e2: nominal,
        candidate_e2: model,
    }
}

#[test]
fn the_session_level_holds_the_false_alarm_rate_over_its_comparisons() {
    // Two folds: one of 8 handclasps and 8 tracker rows (two comparisons), one of 10
    // handclasps and 3 plane rows (the planes pooled with the handclasps: one comparison).
    let e = |n: usize| {
        (0..n)
            .map(|i| 1.0 + 0.1 * (i % 3) as f64)
            .collect::<Vec<f64>>()
    };
    let mut k1 = vec!["coincident"; 8];
    k1.extend(["tracker"; 8]);
    let mut k2 = vec!["coincident"; 10];
    k2.extend(["plane"; 3]);
    let folds = [
        fold("region 1", k1, e(16), e(16)),
        fold("region 2", k2, e(13), e(13)),
    ];
    let j = judge_harm(&folds, HARM_FALSE_ALARM).unwrap();
    assert_eq!(j.comparisons, 3);
    let level = 1.0 - (1.0 - j.alpha_each).powi(3);
    assert!((level - HARM_FALSE_ALARM).abs() < SIDAK_TOL, "{level}");
    let names: Vec<&str> = j.folds[1].kinds.iter().map(|k| k.kind.as_str()).collect();
    assert_eq!(names, ["coincident+plane"]);
    assert_eq!(j.folds[1].kinds[0].rows, 13);
    // Each threshold is Student's quantile at its rows − 1 degrees of freedom.
    for k in j.folds.iter().flat_map(|f| &f.kinds) {
        let want = crate::stats::t_quantile(1.0 - j.alpha_each, k.rows - 1);
        assert_eq!(k.t_harm, want, "{k:?}");
        assert!(!k.harmful);
    }
    assert!(!j.harmful());
    assert!(judge_harm(&folds, 0.0).is_err());
    assert!(judge_harm(&folds, 1.0).is_err());
    assert!(judge_harm(&[], HARM_FALSE_ALARM).is_err());
}

#[test]
fn a_fold_is_harmful_when_one_kind_is_though_the_pool_is_not() {
    // Ten handclasps much better, eight tracker rows clearly worse: pooled, the handclasps'
    // large nominal errors hide the tracker loss; per kind, it shows.
    let mut kinds = vec!["coincident"; 10];
    kinds.extend(["tracker"; 8]);
    let mut nominal = vec![9.0, 11.0, 10.0, 8.0, 12.0, 10.0, 9.5, 10.5, 11.0, 9.0];
    let mut model: Vec<f64> = nominal.iter().map(|e| 0.5 * e).collect();
    nominal.extend([1.0, 1.2, 0.9, 1.1, 1.0, 0.8, 1.0, 1.1]);
    model.extend([2.0, 2.5, 1.9, 2.1, 2.2, 1.7, 2.0, 2.3]);
    let pooled = region_harm(&nominal, &model, HARM_T).unwrap();
    assert!(!pooled.harmful, "{pooled:?}");
    let j = judge_harm(
        &[fold(
            "region 1",
            kinds.clone(),
            nominal.clone(),
            model.clone(),
        )],
        HARM_FALSE_ALARM,
    )
    .unwrap();
    let f = &j.folds[0];
    assert!(f.harmful && j.harmful());
    assert_eq!((f.ratio, f.t), (pooled.ratio, pooled.t));
    assert_eq!(f.kinds.len(), 2);
    assert_eq!(
        (f.kinds[0].kind.as_str(), f.kinds[0].rows),
        ("coincident", 10)
    );
    assert!(!f.kinds[0].harmful && f.kinds[1].harmful);
    // Fewer than MIN_KIND_ROWS tracker rows: pooled with the handclasps, the loss hides.
    let j = judge_harm(
        &[fold(
            "region 1",
            kinds[..16].to_vec(),
            nominal[..16].to_vec(),
            model[..16].to_vec(),
        )],
        HARM_FALSE_ALARM,
    )
    .unwrap();
    assert_eq!(j.comparisons, 1);
    assert_eq!(j.folds[0].kinds[0].kind, "coincident+tracker");
    assert!(!j.harmful(), "{j:?}");
    // Mismatched lengths are an error.
    assert!(judge_harm(
        &[fold(
            "region 1",
            kinds[..5].to_vec(),
            nominal.clone(),
            model.clone()
        )],
        HARM_FALSE_ALARM
    )
    .is_err());
}

#[test]
fn the_single_test_threshold_is_the_one_sided_five_percent_normal_quantile() {
    let want = crate::stats::normal_quantile(1.0 - HARM_FALSE_ALARM);
    assert!((HARM_T - want).abs() < 1e-9, "{HARM_T} vs {want}");
}

// Moved from the CTU study's tests with the rules (issue 19).

#[test]
fn per_kind_rule_refuses_a_candidate_that_buys_contact_fit_with_plane_fit() {
    // Candidates simplest first; kinds (contact, plane). The flexible c2 wins the contact rows
    // by a lot and the pooled error with them, but is worse than one SE on the planes.
    let per_kind = [
        vec![cv(1.00, 0.03), cv(0.95, 0.02)], // c0: offsets
        vec![cv(0.16, 0.02), cv(0.90, 0.02)], // c1: within one SE of the best of both kinds
        vec![cv(0.15, 0.02), cv(0.97, 0.03)], // c2: best contact, plane 0.97 > 0.90 + 0.02
    ];
    let pooled = [cv(0.97, 0.02), cv(0.47, 0.02), cv(0.43, 0.02)];
    assert_eq!(
        pooled_one_se(&pooled),
        Some(2),
        "pooled: 0.47 > 0.43 + 0.02"
    );
    let pick = per_kind_one_se(&per_kind).unwrap();
    assert_eq!(
        pick.best,
        vec![2, 1],
        "smallest contact: c2; smallest plane: c1"
    );
    assert_eq!(pick.qualifies, vec![false, true, false]);
    assert_eq!((pick.index, pick.shortfall), (1, None));
}

#[test]
fn per_kind_rule_takes_the_simplest_qualifying_candidate() {
    // c1 and c2 both qualify on both kinds: the simpler (first) is chosen, not the smaller.
    let per_kind = [
        vec![cv(0.50, 0.01), cv(0.50, 0.01)],
        vec![cv(0.21, 0.02), cv(0.31, 0.02)],
        vec![cv(0.20, 0.02), cv(0.30, 0.02)],
    ];
    let pick = per_kind_one_se(&per_kind).unwrap();
    assert_eq!(pick.qualifies, vec![false, true, true]);
    assert_eq!((pick.index, pick.shortfall), (1, None));
}

#[test]
fn per_kind_rule_falls_back_to_the_smallest_largest_shortfall_when_none_qualifies() {
    // No candidate is within one SE of the best on both kinds; shortfalls in SEs of each
    // kind's best (contact best c2 0.15 ± 0.02, plane best c1 0.90 ± 0.02):
    // c0: max(42.5, 2.5); c1: max(2.5, 0); c2: max(0, 3.5). c1 has the smallest maximum.
    let per_kind = [
        vec![cv(1.00, 0.03), cv(0.95, 0.02)],
        vec![cv(0.20, 0.02), cv(0.90, 0.02)],
        vec![cv(0.15, 0.02), cv(0.97, 0.03)],
    ];
    let pick = per_kind_one_se(&per_kind).unwrap();
    assert_eq!(pick.qualifies, vec![false, false, false]);
    assert_eq!(pick.index, 1);
    let shortfall = pick.shortfall.unwrap();
    assert!((shortfall - 2.5).abs() < ROUND_OFF_TOL, "{shortfall}");
}

/// Round-off of the rule's arithmetic on made-up two-decimal errors.
const ROUND_OFF_TOL: f64 = 1e-9;

#[test]
fn per_kind_rule_with_one_kind_is_the_pooled_one_se_rule() {
    // With one kind the per-kind rule must pick what the one-SE rule picks (the `self` CV has
    // only contact rows): several tables, including one where the pick is not the minimum
    // and one where the minimum is the first candidate.
    let tables: [&[(f64, f64)]; 4] = [
        &[(0.99, 0.01), (0.98, 0.01), (0.13, 0.03), (0.12, 0.03)],
        &[(0.30, 0.01), (0.40, 0.05), (0.50, 0.02)],
        &[(0.50, 0.01), (0.45, 0.01), (0.42, 0.01), (0.41, 0.01)],
        &[(0.2, 0.0), (0.2, 0.0)],
    ];
    let want = [2, 0, 2, 0];
    for (t, want) in tables.iter().zip(want) {
        let pooled: Vec<CvError> = t.iter().map(|&(e, se)| cv(e, se)).collect();
        let per_kind: Vec<Vec<CvError>> = pooled.iter().map(|&c| vec![c]).collect();
        let pick = per_kind_one_se(&per_kind).unwrap();
        assert_eq!(pooled_one_se(&pooled), Some(want), "{t:?}");
        assert_eq!((pick.index, pick.shortfall), (want, None), "{t:?}");
    }
    assert_eq!(per_kind_one_se(&[]), None);
    assert_eq!(per_kind_one_se(&[vec![cv(1.0, 0.1)], vec![]]), None);
}

#[test]
fn cv_error_is_the_rms_with_its_delta_method_standard_error() {
    // e² = 1, 4, 9, 16: mean 7.5, sample variance of e² (42.25 + 12.25 + 2.25 + 72.25) / 3 = 43.
    let c = CvError::from_squares(&[1.0, 4.0, 9.0, 16.0]);
    let e = 7.5f64.sqrt();
    assert!((c.e - e).abs() < ROUND_OFF_TOL);
    assert!((c.se - 43.0f64.sqrt() / (2.0 * e * 2.0)).abs() < ROUND_OFF_TOL);
}

#[test]
fn argmin_takes_the_first_of_equal_values_and_none_when_empty() {
    assert_eq!(argmin(&[3.0, 1.0, 1.0, 2.0]), Some(1));
    assert_eq!(argmin(&[f64::NAN, 2.0]), Some(1));
    assert_eq!(argmin(&[]), None);
}

#[test]
fn pooled_one_se_takes_the_simplest_within_one_se_of_the_smallest() {
    let c = [
        cv(1.10, 0.01),
        cv(1.04, 0.02),
        cv(1.00, 0.05),
        cv(0.99, 0.06),
    ];
    // Smallest 0.99 + 0.06 = 1.05: the first within it is candidate 1.
    assert_eq!(pooled_one_se(&c), Some(1));
    assert_eq!(pooled_one_se(&[]), None);
}

#[test]
fn per_kind_one_se_needs_every_kind_and_falls_back_to_the_smallest_shortfall() {
    // Two kinds. Candidate 0 is best on kind 0, candidate 2 on kind 1.
    let errors = vec![
        vec![cv(1.0, 0.1), cv(3.0, 0.1)],
        vec![cv(1.05, 0.1), cv(2.05, 0.1)],
        vec![cv(1.5, 0.1), cv(2.0, 0.1)],
    ];
    let p = per_kind_one_se(&errors).unwrap();
    assert_eq!(p.best, vec![0, 2]);
    assert_eq!(p.qualifies, vec![false, true, false]);
    assert_eq!((p.index, p.shortfall), (1, None));
    // None qualifies: the smallest largest shortfall (candidate 1: 1.5 SE on kind 0).
    let errors = vec![
        vec![cv(1.0, 0.1), cv(3.0, 0.1)],
        vec![cv(1.15, 0.1), cv(2.15, 0.1)],
        vec![cv(1.5, 0.1), cv(2.0, 0.1)],
    ];
    let p = per_kind_one_se(&errors).unwrap();
    assert_eq!(p.index, 1);
    const TOL: f64 = 1e-9;
    assert!((p.shortfall.unwrap() - 1.5).abs() < TOL);
    // Malformed tables.
    assert_eq!(per_kind_one_se(&[]), None);
    assert_eq!(per_kind_one_se(&[vec![]]), None);
    assert_eq!(per_kind_one_se(&[vec![cv(1.0, 0.1)], vec![]]), None);
}

#[test]
fn one_sample_t_of_gains() {
    // Gains 1, 2, 3: mean 2, sd 1, t = 2 / (1/√3) = 2√3.
    const TOL: f64 = 1e-12;
    assert!((one_sample_t(&[1.0, 2.0, 3.0]) - 2.0 * 3f64.sqrt()).abs() < TOL);
    assert_eq!(one_sample_t(&[0.5, 0.5, 0.5]), f64::INFINITY);
    assert_eq!(one_sample_t(&[-0.5, -0.5]), 0.0);
    assert_eq!(one_sample_t(&[0.0, 0.0]), 0.0);
    assert!(one_sample_t(&[1.0]).is_nan());
}

#[test]
fn do_no_harm_withholds_a_candidate_that_harms_one_region() {
    let nominal = [1.0, 1.0, 1.0, 1.0];
    // Offsets: much better on average, worse in region 3 (extrapolation harm).
    let offsets = vec![0.5, 0.5, 0.5, 1.2];
    // Physical: a little better everywhere.
    let physical = vec![0.8, 0.85, 0.9, 0.95];
    let c = do_no_harm(&nominal, &[offsets, physical]).unwrap();
    assert_eq!(c.eligible, vec![false, true]);
    assert_eq!(c.best, Some(1));
    assert_eq!(c.choice, Some(1));
    assert_eq!(c.withheld, vec![0]);
}

#[test]
fn do_no_harm_takes_nominal_when_nothing_is_eligible() {
    let c = do_no_harm(&[1.0, 2.0], &[vec![0.5, 2.5], vec![1.1, 2.0]]).unwrap();
    assert_eq!(c.eligible, vec![false, false]);
    assert_eq!((c.best, c.threshold, c.choice), (None, None, None));
    // Candidate 1 is nowhere better than nominal: not "withheld", only ineligible.
    assert_eq!(c.withheld, vec![0]);
    let c = do_no_harm(&[1.0], &[]).unwrap();
    assert_eq!(c.choice, None);
}

#[test]
fn do_no_harm_keeps_nominal_when_the_gain_is_within_one_se() {
    // Eligible, mean ratio 0.875, but it gains in one region only: sd 0.25, SE 0.125, so
    // nominal's mean ratio 1 is exactly at the threshold (dyadic numbers: exact arithmetic).
    let c = do_no_harm(&[1.0; 4], &[vec![1.0, 1.0, 1.0, 0.5]]).unwrap();
    assert_eq!(c.best, Some(0));
    assert_eq!(c.threshold, Some(1.0));
    assert_eq!(c.choice, None);
    // Spread evenly, the same mean gain is beyond one SE of nominal: the candidate is taken.
    let c = do_no_harm(&[1.0; 4], &[vec![0.875; 4]]).unwrap();
    assert_eq!(c.choice, Some(0));
}

#[test]
fn do_no_harm_one_se_takes_the_simplest_eligible_within_the_threshold() {
    let nominal = [2.0, 4.0, 1.0];
    let candidates = vec![
        vec![1.9, 3.9, 0.95], // ratios ≈ 0.96: within the threshold? no (see below)
        vec![1.5, 3.0, 0.76], // ratios 0.75, 0.75, 0.76
        vec![1.4, 2.9, 0.74], // ratios 0.70, 0.725, 0.74: best
        vec![1.0, 2.0, 1.5],  // better twice, harmful once: withheld
    ];
    let c = do_no_harm(&nominal, &candidates).unwrap();
    assert_eq!(c.eligible, vec![true, true, true, false]);
    assert_eq!(c.best, Some(2));
    // Threshold ≈ 0.7217 + 0.0117: candidate 1 (0.7533) is not within it, so the best stays.
    assert_eq!(c.choice, Some(2));
    assert_eq!(c.withheld, vec![3]);
    // With a wider spread of the best, the simpler candidate 1 is within one SE.
    let mut wide = candidates.clone();
    wide[2] = vec![1.0, 3.6, 0.72]; // ratios 0.5, 0.9, 0.72: mean 0.7067, SE ≈ 0.116
    let c = do_no_harm(&nominal, &wide).unwrap();
    assert_eq!((c.best, c.choice), (Some(2), Some(1)));
}

#[test]
fn do_no_harm_refuses_malformed_tables() {
    assert_eq!(do_no_harm(&[], &[]), Err(SelectionError::NoRegions));
    assert!(matches!(
        do_no_harm(&[1.0, 0.0], &[]),
        Err(SelectionError::NominalScore { region: 1, .. })
    ));
    assert!(matches!(
        do_no_harm(&[1.0, f64::NAN], &[]),
        Err(SelectionError::NominalScore { region: 1, .. })
    ));
    assert_eq!(
        do_no_harm(&[1.0, 1.0], &[vec![1.0, 1.0], vec![1.0]]),
        Err(SelectionError::RegionCount {
            candidate: 1,
            got: 1,
            expected: 2
        })
    );
    assert!(matches!(
        do_no_harm(&[1.0], &[vec![-0.1]]),
        Err(SelectionError::CandidateScore {
            candidate: 0,
            region: 0,
            ..
        })
    ));
    let msg = do_no_harm(&[1.0], &[vec![f64::INFINITY]])
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("candidate 0") && msg.contains("region 0"),
        "{msg}"
    );
}

/// A table of `regions` nominal scores and `candidates` rows, scores in (0.05, 5).
fn table() -> impl Strategy<Value = (Vec<f64>, Vec<Vec<f64>>)> {
    (1usize..7, 0usize..7).prop_flat_map(|(regions, candidates)| {
        (
            proptest::collection::vec(0.05f64..5.0, regions),
            proptest::collection::vec(proptest::collection::vec(0.05f64..5.0, regions), candidates),
        )
    })
}

proptest! {
    /// The choice is eligible (no ratio above 1), within the one-SE threshold, and the simplest
    /// such; nominal is chosen exactly when nothing is eligible or the threshold reaches 1.
    #[test]
    fn do_no_harm_choice_obeys_the_rule((nominal, candidates) in table()) {
        let c = do_no_harm(&nominal, &candidates).unwrap();
        for (k, r) in c.ratios.iter().enumerate() {
            prop_assert_eq!(c.eligible[k], r.iter().all(|&v| v <= 1.0));
        }
        if let Some(b) = c.best {
            prop_assert!(c.eligible[b]);
            for k in (0..candidates.len()).filter(|&k| c.eligible[k]) {
                prop_assert!(c.mean_ratio[b] <= c.mean_ratio[k]);
            }
        } else {
            prop_assert!(c.eligible.iter().all(|e| !e));
        }
        match c.choice {
            Some(k) => {
                let t = c.threshold.unwrap();
                prop_assert!(c.eligible[k]);
                prop_assert!(c.ratios[k].iter().all(|&v| v <= 1.0));
                prop_assert!(c.mean_ratio[k] <= t && t < 1.0);
                for j in 0..k {
                    prop_assert!(!(c.eligible[j] && c.mean_ratio[j] <= t));
                }
            }
            None => prop_assert!(c.threshold.is_none_or(|t| t >= 1.0)),
        }
        for &w in &c.withheld {
            prop_assert!(!c.eligible[w]);
            prop_assert!(c.ratios[w].iter().any(|&v| v < 1.0));
        }
    }

    /// A candidate that does harm in some region never changes the choice, wherever it is
    /// inserted in the order.
    #[test]
    fn a_harmful_candidate_never_changes_the_choice(
        (nominal, candidates) in table(),
        at in 0usize..8,
        harm in 1.001f64..3.0,
        region in 0usize..7,
        better in 0.1f64..0.99,
    ) {
        let before = do_no_harm(&nominal, &candidates).unwrap();
        let at = at.min(candidates.len());
        let s = region % nominal.len();
        let mut bad: Vec<f64> = nominal.iter().map(|n| n * better).collect();
        bad[s] = nominal[s] * harm;
        let mut more = candidates.clone();
        more.insert(at, bad);
        let after = do_no_harm(&nominal, &more).unwrap();
        let shifted = before.choice.map(|k| if k >= at { k + 1 } else { k });
        prop_assert_eq!(after.choice, shifted);
        // Better than nominal in the other regions (if any): withheld, and listed as such.
        prop_assert_eq!(after.withheld.contains(&at), nominal.len() > 1);
    }

    /// Scaling a region's scores (nominal and every candidate) by a power of two, which keeps
    /// every ratio exact, leaves the choice alone: the rule reads ratios, not units.
    #[test]
    fn do_no_harm_reads_ratios_not_units(
        (nominal, candidates) in table(),
        region in 0usize..7,
        power in -8i32..8,
    ) {
        let s = region % nominal.len();
        let k = 2f64.powi(power);
        let mut n2 = nominal.clone();
        n2[s] *= k;
        let c2: Vec<Vec<f64>> = candidates
            .iter()
            .map(|r| {
                let mut r = r.clone();
                r[s] *= k;
                r
            })
            .collect();
        let a = do_no_harm(&nominal, &candidates).unwrap();
        let b = do_no_harm(&n2, &c2).unwrap();
        prop_assert_eq!(a, b);
    }
}
