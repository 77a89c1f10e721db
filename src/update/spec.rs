//! A self-contained, serialisable description of a [`Problem`]: everything needed to
//! rebuild it exactly, in another process or another language (the scipy comparison
//! of `paper_repro/scipy_multistart.py` reads it).
//!
//! Conventions of the JSON form ([`PROBLEM_SPEC_FORMAT`]):
//! - matrices are row-major nested arrays (`k0[i][j]`), SI units (N/m, kg);
//! - DOFs are 0-based (`dof:0` is floor 1 of a shear frame); an excitation is
//!   `"dof:<e>"` (a force at DOF e) or `"ground"` (ground acceleration, response
//!   relative to the ground);
//! - `magnitude` (and `sigma`) follow the long-vector order of [`crate::frf`]: block by
//!   block, pair by pair, frequency by frequency;
//! - `variables` is the *resolved* [`VariablesConfig`]: bounds and start value of every
//!   variable by name, so defaults changing later cannot change a written problem;
//! - `n_modes` is the resolved number of modes in the modal sums.
//!
//! Floats are written in their shortest round-trip form and read back exactly
//! (serde_json's `float_roundtrip`), so a rebuilt problem gives bit-identical residuals.
//!
//! ```text
//! { "format": "frfbayes-problem/1",
//!   "model": { "k0": [[..], ..], "m0": [[..], ..],
//!              "stiffness_parameters": [{ "name": "k1", "unit": "N/m", "nominal": 1019.0,
//!                                         "influence": [[..], ..] }, ..],
//!              "mass_parameters": [..], "ground_influence": [1.0, ..] },
//!   "blocks": [{ "omega_rad_s": [..],
//!                "pairs": [{ "response": 0, "excitation": "dof:2", "kind": "accelerance" }] }],
//!   "magnitude": [..], "sigma": null, "damping": "rayleigh",
//!   "variables": { .. VariablesConfig .. }, "objective": { "residual": "magnitude",
//!   "n_modes": null }, "n_modes": 4 }
//! ```

use super::problem::{Measurements, ObjectiveOptions, Problem};
use super::variables::{DampingModel, Scale, VariableKind, VariablesConfig};
use crate::error::{Error, Result};
use crate::frf::{Excitation, FrfBlock, FrfKind, FrfPair};
use crate::model::{Parameter, StructuralModel};
use nalgebra::{DMatrix, DVector};
use std::path::Path;

/// Format tag of [`ProblemSpec`] files.
pub const PROBLEM_SPEC_FORMAT: &str = "frfbayes-problem/1";

/// Everything needed to rebuild a [`Problem`] exactly (see the module docs).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProblemSpec {
    /// Always [`PROBLEM_SPEC_FORMAT`].
    pub format: String,
    pub model: ModelSpec,
    pub blocks: Vec<BlockSpec>,
    /// Measured magnitudes `|H^E|` in long-vector order.
    pub magnitude: Vec<f64>,
    /// Optional per-point standard deviations (see [`Measurements::sigma`]).
    #[serde(default)]
    pub sigma: Option<Vec<f64>>,
    pub damping: DampingModel,
    /// The resolved variables (every variable's bounds and start by name).
    pub variables: VariablesConfig,
    pub objective: ObjectiveOptions,
    /// Modes kept in the modal sums (resolved).
    pub n_modes: usize,
}

/// The structural model: `K(alpha) = k0 + sum_r alpha_r K0_r` (Eq. 20) and
/// `M(beta) = m0 + sum_r beta_r M0_r` (Eq. 21).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    /// Nominal stiffness, N/m, row-major.
    pub k0: Vec<Vec<f64>>,
    /// Nominal mass, kg, row-major.
    pub m0: Vec<Vec<f64>>,
    /// One per alpha, in `theta` order.
    pub stiffness_parameters: Vec<ParameterSpec>,
    /// One per beta, in `theta` order.
    pub mass_parameters: Vec<ParameterSpec>,
    /// Ground-motion influence vector (Eq. 13).
    pub ground_influence: Vec<f64>,
}

/// One updating multiplier and its influence matrix.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    pub name: String,
    /// Unit of the physical value (`N/m`, `kg`).
    pub unit: String,
    /// Physical value at multiplier zero, if it has one.
    pub nominal: Option<f64>,
    /// `K0_r` or `M0_r`, row-major.
    pub influence: Vec<Vec<f64>>,
}

/// One frequency grid and its pairs (see [`FrfBlock`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlockSpec {
    pub omega_rad_s: Vec<f64>,
    pub pairs: Vec<PairSpec>,
}

/// One FRF pair (see [`FrfPair`]); `excitation` is `"dof:<e>"` or `"ground"`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairSpec {
    /// Response DOF, 0-based.
    pub response: usize,
    #[serde(with = "excitation_text")]
    pub excitation: Excitation,
    pub kind: FrfKind,
}

/// `Excitation` as `"dof:<e>"` / `"ground"`.
mod excitation_text {
    use crate::frf::Excitation;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(e: &Excitation, s: S) -> Result<S::Ok, S::Error> {
        match e {
            Excitation::Dof(d) => s.serialize_str(&format!("dof:{d}")),
            Excitation::Ground => s.serialize_str("ground"),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Excitation, D::Error> {
        let text = String::deserialize(d)?;
        if text == "ground" {
            return Ok(Excitation::Ground);
        }
        text.strip_prefix("dof:")
            .and_then(|n| n.parse().ok())
            .map(Excitation::Dof)
            .ok_or_else(|| {
                serde::de::Error::custom(format!(
                    "excitation '{text}' must be \"ground\" or \"dof:<0-based DOF>\""
                ))
            })
    }
}

fn to_rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

fn from_rows(what: &str, rows: &[Vec<f64>], n: usize) -> Result<DMatrix<f64>> {
    if rows.len() != n {
        return Err(Error::Usage(format!(
            "{what} has {} rows, expected {n} (the size of k0)",
            rows.len()
        )));
    }
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != n) {
        return Err(Error::Usage(format!(
            "{what} row {i} has {} entries, expected {n}",
            r.len()
        )));
    }
    Ok(DMatrix::from_fn(n, n, |i, j| rows[i][j]))
}

impl Problem {
    /// The problem as a [`ProblemSpec`]; [`Problem::from_spec`] rebuilds it exactly.
    pub fn spec(&self) -> ProblemSpec {
        let model = self.model();
        let params = |ps: &[Parameter], ms: &[DMatrix<f64>]| -> Vec<ParameterSpec> {
            ps.iter()
                .zip(ms)
                .map(|(p, m)| ParameterSpec {
                    name: p.name.clone(),
                    unit: p.unit.clone(),
                    nominal: p.nominal,
                    influence: to_rows(m),
                })
                .collect()
        };
        let model_spec = ModelSpec {
            k0: to_rows(&model.stiffness(&model.alpha_zero())),
            m0: to_rows(&model.mass(&model.beta_zero())),
            stiffness_parameters: params(model.alpha_parameters(), model.stiffness_influence()),
            mass_parameters: params(model.beta_parameters(), model.mass_influence()),
            ground_influence: model.ground_influence().iter().copied().collect(),
        };
        let blocks = self
            .blocks()
            .iter()
            .map(|b| BlockSpec {
                omega_rad_s: b.omega_rad_s.clone(),
                pairs: b
                    .pairs
                    .iter()
                    .map(|p| PairSpec {
                        response: p.response,
                        excitation: p.excitation,
                        kind: p.kind,
                    })
                    .collect(),
            })
            .collect();
        ProblemSpec {
            format: PROBLEM_SPEC_FORMAT.into(),
            model: model_spec,
            blocks,
            magnitude: self.measured().to_vec(),
            sigma: self.sigma().map(|s| s.to_vec()),
            damping: self.variables().damping_model(),
            variables: self.resolved_variables(),
            objective: *self.options(),
            n_modes: self.n_modes(),
        }
    }

    /// The variables as a config naming every variable's bounds and start value (and
    /// the fixed ones), independent of [`VariablesConfig`]'s defaults.
    pub fn resolved_variables(&self) -> VariablesConfig {
        let vars = self.variables().variables();
        let mut c = VariablesConfig {
            log_damping: vars
                .iter()
                .filter(|v| !matches!(v.kind, VariableKind::Alpha(_) | VariableKind::Beta(_)))
                .all(|v| v.scale == Scale::Log),
            ..Default::default()
        };
        for v in vars {
            c.bounds.insert(v.name.clone(), [v.lower, v.upper]);
            c.initial.insert(v.name.clone(), v.initial);
            if let Some(x) = v.fixed {
                c.fixed.insert(v.name.clone(), x);
            }
        }
        c
    }

    /// Rebuilds a problem from its spec, validating it as [`Problem::new`] does.
    pub fn from_spec(spec: &ProblemSpec) -> Result<Problem> {
        if spec.format != PROBLEM_SPEC_FORMAT {
            return Err(Error::Usage(format!(
                "problem format '{}' is not supported (expected '{PROBLEM_SPEC_FORMAT}')",
                spec.format
            )));
        }
        let ms = &spec.model;
        let n = ms.k0.len();
        let params = |what: &str, ps: &[ParameterSpec]| -> Result<Vec<(Parameter, DMatrix<f64>)>> {
            ps.iter()
                .map(|p| {
                    let m = from_rows(&format!("{what} influence of {}", p.name), &p.influence, n)?;
                    let param = Parameter {
                        name: p.name.clone(),
                        unit: p.unit.clone(),
                        nominal: p.nominal,
                    };
                    Ok((param, m))
                })
                .collect()
        };
        let model = StructuralModel::from_matrices(
            from_rows("k0", &ms.k0, n)?,
            from_rows("m0", &ms.m0, n)?,
            params("stiffness", &ms.stiffness_parameters)?,
            params("mass", &ms.mass_parameters)?,
            Some(DVector::from_column_slice(&ms.ground_influence)),
        )?;
        let mut names: Vec<&str> = ms
            .stiffness_parameters
            .iter()
            .chain(&ms.mass_parameters)
            .map(|p| p.name.as_str())
            .collect();
        names.sort_unstable();
        if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
            return Err(Error::Usage(format!(
                "two model parameters are named '{}'; names must be unique",
                w[0]
            )));
        }
        let blocks = spec
            .blocks
            .iter()
            .map(|b| FrfBlock {
                omega_rad_s: b.omega_rad_s.clone(),
                pairs: b
                    .pairs
                    .iter()
                    .map(|p| FrfPair {
                        response: p.response,
                        excitation: p.excitation,
                        kind: p.kind,
                    })
                    .collect(),
            })
            .collect();
        let data = Measurements {
            blocks,
            magnitude: spec.magnitude.clone(),
            sigma: spec.sigma.clone(),
        };
        let problem = Problem::new(model, data, spec.damping, &spec.variables, spec.objective)?;
        if problem.n_modes() != spec.n_modes {
            return Err(Error::Usage(format!(
                "n_modes is {} but the objective options give {}",
                spec.n_modes,
                problem.n_modes()
            )));
        }
        Ok(problem)
    }
}

impl ProblemSpec {
    /// Reads a spec from a JSON file; errors name the file, line and column.
    pub fn read(path: &Path) -> Result<ProblemSpec> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_str(&text).map_err(|e| Error::invalid(path, e.to_string()))
    }

    /// Writes the spec as JSON, atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string(self)
            .map_err(|e| Error::invalid(path, format!("cannot serialise problem: {e}")))?;
        crate::io::write_atomic(path, text.as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::update::{start_points, update, MultistartOptions, ResidualForm};

    fn problem(damping: DampingModel, residual: ResidualForm, sigma: bool) -> Problem {
        let model =
            StructuralModel::shear_frame(&[4.64, 4.64, 4.7], &[1019.0, 1217.0, 1420.3]).unwrap();
        let omega_rad_s: Vec<f64> = (1..=40).map(|i| 0.7 * i as f64 + 0.1 / 3.0).collect();
        let pair = |response, excitation, kind| FrfPair {
            response,
            excitation,
            kind,
        };
        let blocks = vec![
            FrfBlock {
                omega_rad_s: omega_rad_s.clone(),
                pairs: vec![
                    pair(0, Excitation::Dof(2), FrfKind::Accelerance),
                    pair(2, Excitation::Dof(2), FrfKind::Receptance),
                ],
            },
            FrfBlock {
                omega_rad_s: omega_rad_s[5..].to_vec(),
                pairs: vec![pair(1, Excitation::Ground, FrfKind::Mobility)],
            },
        ];
        let len = 2 * 40 + 35;
        // Irrational-looking values so every float exercises the round trip.
        let magnitude: Vec<f64> = (0..len).map(|k| (1.0 + k as f64).sqrt() / 7.0).collect();
        let sigma = sigma.then(|| {
            (0..len)
                .map(|k| 0.01 + (k as f64).sin().abs() / 3.0)
                .collect()
        });
        let mut config = VariablesConfig::default();
        config.fixed.insert("m1".into(), 1.0 / 30.0);
        config.initial.insert("k2".into(), 0.1 / 3.0);
        let options = ObjectiveOptions {
            residual,
            n_modes: Some(2),
        };
        let data = Measurements {
            blocks,
            magnitude,
            sigma,
        };
        Problem::new(model, data, damping, &config, options).unwrap()
    }

    /// Residuals at the start and at a few Latin hypercube points, bit for bit.
    fn assert_same(a: &Problem, b: &Problem) {
        let opts = MultistartOptions {
            n_starts: 4,
            seed: 3,
            ..Default::default()
        };
        let starts = start_points(a, &opts).unwrap();
        assert_eq!(starts, start_points(b, &opts).unwrap());
        for theta in &starts {
            let (ra, rb) = (
                a.residuals_at(theta).unwrap(),
                b.residuals_at(theta).unwrap(),
            );
            assert!(ra.iter().zip(&rb).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
        assert_eq!(a.variables().variables(), b.variables().variables());
        assert_eq!(a.weights(), b.weights());
    }

    #[test]
    fn json_round_trip_is_exact() {
        for (damping, residual, sigma) in [
            (DampingModel::Rayleigh, ResidualForm::Magnitude, false),
            (DampingModel::Caughey, ResidualForm::LogMagnitude, false),
            (DampingModel::Caughey, ResidualForm::Magnitude, true),
        ] {
            let p = problem(damping, residual, sigma);
            let spec = p.spec();
            let json = serde_json::to_string(&spec).unwrap();
            let back: ProblemSpec = serde_json::from_str(&json).unwrap();
            assert_eq!(back, spec);
            let q = Problem::from_spec(&back).unwrap();
            assert_same(&p, &q);
            assert_eq!(q.spec(), spec);
        }
    }

    #[test]
    fn rebuilt_problem_fits_alike() {
        let p = problem(DampingModel::Rayleigh, ResidualForm::Magnitude, false);
        let q = Problem::from_spec(&p.spec()).unwrap();
        let opts = MultistartOptions {
            n_starts: 3,
            seed: 1,
            ..Default::default()
        };
        let (a, b) = (update(&p, &opts).unwrap(), update(&q, &opts).unwrap());
        assert_eq!(a.best.theta, b.best.theta);
        assert_eq!(a.best.cost.to_bits(), b.best.cost.to_bits());
        for (s, t) in a.starts.iter().zip(start_points(&p, &opts).unwrap()) {
            assert_eq!(s.start, t);
        }
    }

    #[test]
    fn rejects_bad_specs() {
        let p = problem(DampingModel::Caughey, ResidualForm::Magnitude, false);
        let mut s = p.spec();
        s.model.m0[1].pop();
        let e = Problem::from_spec(&s).unwrap_err().to_string();
        assert!(e.contains("m0 row 1 has 2 entries, expected 3"), "{e}");
        let mut s = p.spec();
        s.n_modes = 3;
        let e = Problem::from_spec(&s).unwrap_err().to_string();
        assert!(e.contains("n_modes is 3"), "{e}");
        let mut s = p.spec();
        s.model.mass_parameters[1].name = "k1".into();
        let e = Problem::from_spec(&s).unwrap_err().to_string();
        assert!(e.contains("named 'k1'"), "{e}");
        let json = serde_json::to_string(&p.spec())
            .unwrap()
            .replace("\"dof:2\"", "\"floor 3\"");
        let e = serde_json::from_str::<ProblemSpec>(&json)
            .unwrap_err()
            .to_string();
        assert!(e.contains("excitation 'floor 3'"), "{e}");
    }
}
