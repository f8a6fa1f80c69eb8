//! Coupled joints: a joint of the chain whose value is a linear combination of other joints'
//! values, `q_k = Σ c_i·q_i + c_0` (a URDF `<mimic>`, a parallelogram linkage, a humanoid's
//! torso joint that follows two others).
//!
//! The user supplies the chain's **independent** joints (the joint vector `q` of every function
//! of this crate, [`RobotModel::dof`](crate::RobotModel::dof) values); the coupled joints' values
//! are computed from them. A coupling may name other coupled joints: it is resolved, by
//! substitution, into a [`LinearCoupling`] over the independent joints (a cycle is refused).
//! Units: each value in its joint's unit (rad for revolute and continuous joints, m for prismatic
//! ones), so a coefficient is (unit of the coupled joint) per (unit of the driving joint) and the
//! offset is in the coupled joint's unit.

use std::collections::HashMap;

/// A coupling as declared, by joint names: `q[joint] = Σ coefficient·q[name] + offset`.
///
/// From a URDF `<mimic joint="name" multiplier="c" offset="c0"/>` (one term, see
/// [`JointCoupling::mimic`]) or declared by the caller (e.g. a cell file) and attached with
/// [`RobotModel::with_couplings`](crate::RobotModel::with_couplings). The named joints must lie on
/// the chain to the tool link; a named joint may itself be coupled.
#[derive(Debug, Clone, PartialEq)]
pub struct JointCoupling {
    /// The coupled joint's URDF name.
    pub joint: String,
    /// `(driving joint's URDF name, coefficient)`: the coefficient in (unit of `joint`) per (unit
    /// of the driving joint), i.e. rad/rad, m/m, m/rad or rad/m.
    pub terms: Vec<(String, f64)>,
    /// Constant term, in the coupled joint's unit (rad, or m for a prismatic joint).
    pub offset: f64,
}

impl JointCoupling {
    /// The coupling of a URDF `<mimic joint="mimicked" multiplier offset>`:
    /// `q[joint] = multiplier·q[mimicked] + offset`.
    pub fn mimic(joint: &str, mimicked: &str, multiplier: f64, offset: f64) -> JointCoupling {
        JointCoupling {
            joint: joint.to_string(),
            terms: vec![(mimicked.to_string(), multiplier)],
            offset,
        }
    }
}

/// A coupled joint's value in terms of the independent joint vector `q`:
/// `Σ coefficient·q[index] + offset` ([`LinearCoupling::value`]).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearCoupling {
    /// `(index into q, 0-based; coefficient)`, one term per independent joint it depends on, in
    /// increasing index order. The coefficient is also `∂q_k/∂q[index]`.
    pub terms: Vec<(usize, f64)>,
    /// Constant term, in the coupled joint's unit (rad or m).
    pub offset: f64,
}

impl LinearCoupling {
    /// The coupled joint's value at the independent joint vector `q` (a missing entry counts as
    /// 0).
    pub fn value(&self, q: &[f64]) -> f64 {
        self.terms.iter().fold(self.offset, |acc, &(i, c)| {
            acc + c * q.get(i).copied().unwrap_or(0.0)
        })
    }
}

/// A chain joint's coupling as declared, over chain joint indices: `Some((terms, offset))`, or
/// `None` for an independent joint.
type Declared = Option<(Vec<(usize, f64)>, f64)>;

/// What is wrong with a set of couplings (the model turns it into a [`crate::ModelError`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum CouplingProblem {
    /// Coupling `index` (of the list given to [`resolve`]) names `missing`, which is not a moving
    /// joint of the chain.
    NotOnChain { index: usize, missing: String },
    /// Two couplings for the same joint.
    Duplicate { joint: String },
    /// A coefficient or offset of `joint`'s coupling is not finite.
    NotFinite { joint: String },
    /// The couplings refer to each other in a loop (the joints on it, in order).
    Cycle { joints: Vec<String> },
    /// Every joint of the chain would be coupled: nothing is left to supply.
    AllCoupled,
}

/// Resolves `couplings` over the chain's moving joints `chain` (names, in chain order) into one
/// entry per chain joint: `None` for an independent joint, the [`LinearCoupling`] over the
/// independent joints (numbered in chain order) for a coupled one.
pub(crate) fn resolve(
    chain: &[&str],
    couplings: &[JointCoupling],
) -> Result<Vec<Option<LinearCoupling>>, CouplingProblem> {
    let index: HashMap<&str, usize> = chain.iter().enumerate().map(|(k, n)| (*n, k)).collect();
    // declared[k]: the coupling of chain joint k over chain joint indices.
    let mut declared: Vec<Declared> = vec![None; chain.len()];
    for (c_index, c) in couplings.iter().enumerate() {
        let not_on_chain = |name: &str| CouplingProblem::NotOnChain {
            index: c_index,
            missing: name.to_string(),
        };
        let &k = index
            .get(c.joint.as_str())
            .ok_or_else(|| not_on_chain(&c.joint))?;
        let mut terms = Vec::with_capacity(c.terms.len());
        for (name, coefficient) in &c.terms {
            let &j = index.get(name.as_str()).ok_or_else(|| not_on_chain(name))?;
            terms.push((j, *coefficient));
        }
        if !(c.offset.is_finite() && terms.iter().all(|(_, x)| x.is_finite())) {
            return Err(CouplingProblem::NotFinite {
                joint: c.joint.clone(),
            });
        }
        if declared[k].is_some() {
            return Err(CouplingProblem::Duplicate {
                joint: c.joint.clone(),
            });
        }
        declared[k] = Some((terms, c.offset));
    }
    let mut q_index = vec![usize::MAX; chain.len()];
    let mut n_independent = 0;
    for (k, d) in declared.iter().enumerate() {
        if d.is_none() {
            q_index[k] = n_independent;
            n_independent += 1;
        }
    }
    if n_independent == 0 && !chain.is_empty() {
        return Err(CouplingProblem::AllCoupled);
    }
    // Depth-first substitution with the usual three states (unvisited, on the stack, done).
    let mut resolved: Vec<Option<LinearCoupling>> = vec![None; chain.len()];
    let mut state = vec![0u8; chain.len()];
    for k in 0..chain.len() {
        if declared[k].is_some() {
            let mut stack = Vec::new();
            resolve_one(
                k,
                chain,
                &declared,
                &q_index,
                &mut state,
                &mut stack,
                &mut resolved,
            )?;
        }
    }
    Ok(resolved)
}

/// Resolves chain joint `k` (coupled) into `resolved[k]`, recursing into the coupled joints it
/// names.
fn resolve_one(
    k: usize,
    chain: &[&str],
    declared: &[Declared],
    q_index: &[usize],
    state: &mut [u8],
    stack: &mut Vec<usize>,
    resolved: &mut [Option<LinearCoupling>],
) -> Result<(), CouplingProblem> {
    match state[k] {
        2 => return Ok(()),
        1 => {
            let from = stack.iter().position(|&s| s == k).unwrap_or(0);
            let mut joints: Vec<String> = stack[from..].iter().map(|&s| chain[s].into()).collect();
            joints.push(chain[k].into());
            return Err(CouplingProblem::Cycle { joints });
        }
        _ => {}
    }
    state[k] = 1;
    stack.push(k);
    let (terms, offset) = declared[k].as_ref().expect("called for coupled joints");
    let mut sum: Vec<f64> = Vec::new();
    let mut constant = *offset;
    fn add(i: usize, c: f64, sum: &mut Vec<f64>) {
        if sum.len() <= i {
            sum.resize(i + 1, 0.0);
        }
        sum[i] += c;
    }
    for &(j, c) in terms {
        if declared[j].is_none() {
            add(q_index[j], c, &mut sum);
        } else {
            resolve_one(j, chain, declared, q_index, state, stack, resolved)?;
            let inner = resolved[j].as_ref().expect("just resolved");
            for &(i, ci) in &inner.terms {
                add(i, c * ci, &mut sum);
            }
            constant += c * inner.offset;
        }
    }
    // Every independent joint named (even with a zero total) keeps its term: ∂q_k/∂q_i is then
    // an exact 0, and the set of joints a coupled joint depends on is what was declared.
    let mut named = vec![false; sum.len()];
    mark_named(k, declared, q_index, &mut named);
    resolved[k] = Some(LinearCoupling {
        terms: sum
            .iter()
            .enumerate()
            .filter(|(i, _)| named.get(*i).copied().unwrap_or(false))
            .map(|(i, &c)| (i, c))
            .collect(),
        offset: constant,
    });
    stack.pop();
    state[k] = 2;
    Ok(())
}

/// Marks the independent joints that coupled joint `k` names, directly or through other coupled
/// joints (the recursion ends: [`resolve_one`] has refused cycles before this runs).
fn mark_named(k: usize, declared: &[Declared], q_index: &[usize], named: &mut Vec<bool>) {
    if let Some((terms, _)) = &declared[k] {
        for &(j, _) in terms {
            if declared[j].is_none() {
                let i = q_index[j];
                if named.len() <= i {
                    named.resize(i + 1, false);
                }
                named[i] = true;
            } else {
                mark_named(j, declared, q_index, named);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(joint: &str, terms: &[(&str, f64)], offset: f64) -> JointCoupling {
        JointCoupling {
            joint: joint.into(),
            terms: terms.iter().map(|(n, x)| (n.to_string(), *x)).collect(),
            offset,
        }
    }

    #[test]
    fn one_to_many_and_chained_couplings_resolve_over_the_independent_joints() {
        // j4 = −(j1 + j2), j5 = 2·j4 + 0.1 = −2 j1 − 2 j2 + 0.1; independent j1, j2, j3 → q 0, 1, 2.
        let chain = ["j1", "j2", "j3", "j4", "j5"];
        let r = resolve(
            &chain,
            &[
                c("j5", &[("j4", 2.0)], 0.1),
                c("j4", &[("j1", -1.0), ("j2", -1.0)], 0.0),
            ],
        )
        .unwrap();
        assert_eq!(r[..3], [None, None, None]);
        assert_eq!(
            r[3],
            Some(LinearCoupling {
                terms: vec![(0, -1.0), (1, -1.0)],
                offset: 0.0
            })
        );
        assert_eq!(
            r[4],
            Some(LinearCoupling {
                terms: vec![(0, -2.0), (1, -2.0)],
                offset: 0.1
            })
        );
        assert_eq!(r[4].as_ref().unwrap().value(&[0.5, 0.25, 9.0]), -1.4);
        // A coupled joint in the middle: the independent joints are numbered around it.
        let r = resolve(&["a", "b", "c"], &[c("b", &[("c", 0.5)], 0.0)]).unwrap();
        assert_eq!(
            r[1],
            Some(LinearCoupling {
                terms: vec![(1, 0.5)],
                offset: 0.0
            })
        );
    }

    #[test]
    fn bad_couplings_are_refused_with_their_cause() {
        let chain = ["a", "b", "c"];
        assert_eq!(
            resolve(&chain, &[c("b", &[("x", 1.0)], 0.0)]),
            Err(CouplingProblem::NotOnChain {
                index: 0,
                missing: "x".into()
            })
        );
        assert_eq!(
            resolve(&chain, &[c("z", &[("a", 1.0)], 0.0)]),
            Err(CouplingProblem::NotOnChain {
                index: 0,
                missing: "z".into()
            })
        );
        assert_eq!(
            resolve(
                &chain,
                &[c("b", &[("a", 1.0)], 0.0), c("b", &[("c", 1.0)], 0.0)]
            ),
            Err(CouplingProblem::Duplicate { joint: "b".into() })
        );
        assert_eq!(
            resolve(&chain, &[c("b", &[("a", f64::NAN)], 0.0)]),
            Err(CouplingProblem::NotFinite { joint: "b".into() })
        );
        assert_eq!(
            resolve(
                &chain,
                &[c("b", &[("c", 1.0)], 0.0), c("c", &[("b", 1.0)], 0.0)]
            ),
            Err(CouplingProblem::Cycle {
                joints: vec!["b".into(), "c".into(), "b".into()]
            })
        );
        assert_eq!(
            resolve(&chain, &[c("a", &[("a", 1.0)], 0.0)]),
            Err(CouplingProblem::Cycle {
                joints: vec!["a".into(), "a".into()]
            })
        );
        assert_eq!(
            resolve(
                &["a"],
                &[c("a", &[], 0.3)] // a constant: nothing left to supply
            ),
            Err(CouplingProblem::AllCoupled)
        );
    }
}
