//! The greedy experiment design ([`greedy_design`]) against random subsets.

use super::*;

/// Candidate handclasps (noise-free pairs of the nominal cell) as coincident observations.
fn candidates(sc: &SimCell, n: usize, sigma: f64, seed: u64) -> Vec<Observation> {
    sc.eval_pairs(n, 0.9, seed)
        .into_iter()
        .enumerate()
        .map(|(i, pair)| Observation {
            row: i + 1,
            kind: ObservationKind::Coincident {
                q1: pair.q1,
                q2: pair.q2,
                tool1: 0,
                tool2: 0,
                noise: Noise3::Isotropic { sigma_m: sigma },
            },
        })
        .collect()
}

/// The greedy A-optimal (cooperative) and D-optimal choices of 20 of 120 candidates beat every
/// one of 20 seeded random subsets of the same size on their own criterion, and the criterion
/// the design reports equals the one recomputed from scratch for its chosen set.
#[test]
fn greedy_design_beats_random_subsets_on_its_criterion() {
    let mut sc = sim_cell(Cell::Wall, realistic(), false, 61);
    let x = sc.truth.b1_from_b2;
    sc.truth = CellEstimate::nominal(&sc.problem(), x);
    let p = sc.problem();
    let cands = candidates(&sc, 120, 3e-4, 62);
    let eval = sc.eval_pairs(60, 0.7, 63);
    let layout = ParamLayout::new(&p, &[]);
    let at = CellEstimate::nominal(&p, x);
    let mut rng = ChaCha8Rng::seed_from_u64(64);
    for crit in [DesignCriterion::CooperativeA, DesignCriterion::D] {
        let d = greedy_design(&p, &layout, &at, &cands, &eval, 20, crit).unwrap();
        assert_eq!(d.chosen.len(), 20);
        let again = design_criterion(&p, &layout, &at, &cands, &d.chosen, &eval, crit).unwrap();
        assert!(
            (again - d.criterion).abs() <= 1e-6 * d.criterion.abs(),
            "{crit:?}: Woodbury {} vs direct {again}",
            d.criterion
        );
        let mut random = Vec::new();
        for _ in 0..20 {
            let mut idx: Vec<usize> = (0..cands.len()).collect();
            for i in 0..20 {
                let j = rng.random_range(i..idx.len());
                idx.swap(i, j);
            }
            random
                .push(design_criterion(&p, &layout, &at, &cands, &idx[..20], &eval, crit).unwrap());
        }
        let mean = random.iter().sum::<f64>() / random.len() as f64;
        eprintln!(
            "{crit:?}: greedy {:.6e}, random mean {:.6e}",
            d.criterion, mean
        );
        for r in &random {
            match crit {
                DesignCriterion::CooperativeA => assert!(d.criterion < *r),
                _ => assert!(d.criterion > *r),
            }
        }
    }
}
