//! End-to-end tests for `handclasp paper diagnose` (small seeded Monte Carlo to stay fast).

use crate::support::{handclasp, stdout_json};

/// `handclasp paper diagnose` followed by `args`.
fn run(args: &[&str]) -> std::process::Output {
    handclasp(&[&["paper", "diagnose"][..], args].concat())
}

/// The JSON object carries the σ fit, the per-cell rows, every candidate with its fitted parameters,
/// log-likelihood, AIC and held-out score, and the named cause; the same seed gives the same bytes.
#[test]
fn paper_diagnose_json_has_the_documented_fields_and_is_seeded() {
    let args = [
        "--json",
        "--seed",
        "3",
        "--trials",
        "300",
        "--bootstrap",
        "0",
    ];
    let out = run(&args);
    let v = stdout_json(&out);
    let common = v["study"]["common"].as_array().unwrap();
    assert_eq!(common.len(), 2);
    for c in common {
        let s = c["common"]["sigma_mm"].as_f64().unwrap();
        let ci = c["common"]["ci95_mm"].as_array().unwrap();
        assert!(ci[0].as_f64().unwrap() <= s && s <= ci[1].as_f64().unwrap());
        // Table 1's errors are millimetres: σ̂ between 0.5 and 20 mm.
        assert!(s > 0.5 && s < 20.0, "σ̂ {s}");
    }
    assert_eq!(v["study"]["rows"].as_array().unwrap().len(), 30);
    assert_eq!(v["cells"].as_array().unwrap().len(), 3);
    assert_eq!(v["signed"].as_array().unwrap().len(), 15);
    let cands = v["candidates"].as_array().unwrap();
    assert!(cands.len() >= 5);
    for c in cands {
        for k in ["loglik", "aic", "heldout_loglik", "lr_p_value"] {
            assert!(c[k].as_f64().unwrap().is_finite(), "{k} in {c}");
        }
    }
    assert!(v["cause"].as_str().is_some());
    // Floor-wall's generic estimates share a sign in every component (5 of 5).
    let wall = &v["cells"][2];
    assert_eq!(wall["cell"], "floor-wall");
    assert!(wall["same_sign"]
        .as_array()
        .unwrap()
        .iter()
        .all(|x| x.as_u64() == Some(5)));
    let again = run(&args);
    assert_eq!(out.stdout, again.stdout);
}

/// The text report names the cause and flags measurements outside the simulated band.
#[test]
fn paper_diagnose_text_names_a_cause() {
    let out = run(&["--trials", "300", "--bootstrap", "0"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Named cause:"), "{text}");
    assert!(text.contains("σ̂"), "{text}");
}

/// Too few trials is an error naming the option and the minimum.
#[test]
fn paper_diagnose_rejects_too_few_trials() {
    let out = run(&["--trials", "5"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("trials") && err.contains("200"), "{err}");
}
