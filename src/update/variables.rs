//! The updating variables `theta` of Eqs. (22e-f) and (24e-f) and their box bounds.
//!
//! Layout of `theta` (always the full layout, fixed variables included): the stiffness
//! multipliers `alpha_1..alpha_na` (Eq. 20), the mass multipliers `beta_1..beta_nb`
//! (Eq. 21), then the damping variables: Rayleigh `a0` (1/s), `a1` (s) (Eq. 2), or
//! Caughey `xi_1..xi_m` (Eq. 9), one per retained mode. Names follow the model
//! (`k1..`, `m1..` for a shear frame), then `a0`, `a1` or `xi1..`.
//!
//! The solver works on the *internal* vector `z` of the free variables only, with the
//! damping variables on a log scale by default (`z = ln a0`, ...): Rayleigh's `a1`
//! spans seven decades, and relative changes are what matter for damping. Bounds are
//! always given in physical units.

use crate::error::{Error, Result};
use crate::model::{Damping, StructuralModel};
use crate::update::lsq::Bounds;
use std::collections::BTreeMap;

/// Which damping model is updated with the structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DampingModel {
    /// `C = a0 M + a1 K`: variables `a0` (1/s), `a1` (s); Eqs. (7), (15), (22).
    Rayleigh,
    /// Modal damping ratios `xi_i`, one per retained mode; Eqs. (10), (16), (24).
    Caughey,
}

/// Bounds, start values and fixed values of the updating variables.
///
/// Defaults, and why:
/// - `alpha` in [-0.3, 0.3]: the paper's updated story stiffnesses lie within -4 % to
///   +10 % of nominal (Tables 1-2); +-30 % leaves room for a poor nominal model.
/// - `beta` in [-0.1, 0.111]: the paper's updated masses never exceed 5.155 kg =
///   1.111 x 4.64 kg, reached nine times in Tables 1-2, so 0.111 is the paper's upper
///   bound on beta. (Every variant also returns m3 = 4.949 kg = 1.0666 x 4.64 kg, and
///   m4 never exceeds 5.143 kg = 1.1084 x 4.64 kg; these look like the paper's lower
///   bound for m3 and upper bound for m4, see `bounds` to impose them.)
/// - `a0_per_s` in [1e-4, 1] 1/s and `a1_s` in [1e-10, 1e-3] s: "large" damping bounds
///   (Section 4.2); Table 1's a1 = 1e-10 s sits on this lower bound.
/// - `xi` in [1e-4, 0.1]: the paper's ratios are 0.2 % to 1.7 %.
/// - Start values: alpha = beta = 0 (nominal), `a0` = 0.01 1/s, `a1` = 1e-6 s,
///   `xi` = 0.01, the paper's initial values.
///
/// # Example
/// ```
/// use frfbayes::update::VariablesConfig;
/// let c: VariablesConfig = toml::from_str(r#"
///     beta = [-0.05, 0.111]
///     bounds = { m3 = [0.0666, 0.111] }
///     fixed = { m1 = 0.0 }
/// "#).unwrap();
/// assert_eq!(c.alpha, [-0.3, 0.3]);
/// assert_eq!(c.bounds["m3"], [0.0666, 0.111]);
/// ```
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VariablesConfig {
    /// [lower, upper] of every stiffness multiplier alpha (dimensionless).
    pub alpha: [f64; 2],
    /// [lower, upper] of every mass multiplier beta (dimensionless).
    pub beta: [f64; 2],
    /// [lower, upper] of Rayleigh's a0 in 1/s.
    pub a0_per_s: [f64; 2],
    /// [lower, upper] of Rayleigh's a1 in s.
    pub a1_s: [f64; 2],
    /// [lower, upper] of every Caughey damping ratio.
    pub xi: [f64; 2],
    /// Start value of a0 (1/s).
    pub initial_a0_per_s: f64,
    /// Start value of a1 (s).
    pub initial_a1_s: f64,
    /// Start value of every xi.
    pub initial_xi: f64,
    /// Optimise damping variables on a log scale (bounds stay physical). Default true.
    pub log_damping: bool,
    /// Per-variable [lower, upper] overriding the above, by name (`k2`, `m3`, `a1`,
    /// `xi4`).
    pub bounds: BTreeMap<String, [f64; 2]>,
    /// Per-variable start values, by name.
    pub initial: BTreeMap<String, f64>,
    /// Variables held at a value and not updated, by name (multipliers for alpha and
    /// beta, physical units for damping). Use it to remove the mass-stiffness scale
    /// ridge of ground-excitation data (see [`crate::update`]).
    pub fixed: BTreeMap<String, f64>,
}

impl Default for VariablesConfig {
    fn default() -> Self {
        VariablesConfig {
            alpha: [-0.3, 0.3],
            beta: [-0.1, 0.111],
            a0_per_s: [1e-4, 1.0],
            a1_s: [1e-10, 1e-3],
            xi: [1e-4, 0.1],
            initial_a0_per_s: 0.01,
            initial_a1_s: 1e-6,
            initial_xi: 0.01,
            log_damping: true,
            bounds: BTreeMap::new(),
            initial: BTreeMap::new(),
            fixed: BTreeMap::new(),
        }
    }
}

/// What a variable is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VariableKind {
    /// Stiffness multiplier of influence matrix r (0-based).
    Alpha(usize),
    /// Mass multiplier of influence matrix r (0-based).
    Beta(usize),
    /// Rayleigh mass-proportional coefficient (1/s).
    A0,
    /// Rayleigh stiffness-proportional coefficient (s).
    A1,
    /// Caughey damping ratio of mode i (0-based).
    Xi(usize),
}

/// How a variable is represented internally.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// `z = theta`.
    Linear,
    /// `z = ln theta` (requires a positive lower bound).
    Log,
}

/// One updating variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    pub name: String,
    /// Unit of the variable itself (`1` for multipliers).
    pub unit: String,
    pub kind: VariableKind,
    pub lower: f64,
    pub upper: f64,
    pub initial: f64,
    pub scale: Scale,
    /// `Some(value)` when the variable is held fixed.
    pub fixed: Option<f64>,
}

/// The variables of one updating problem and the map between `theta` and the
/// solver's internal vector `z`.
#[derive(Debug, Clone)]
pub struct Variables {
    vars: Vec<Variable>,
    n_alpha: usize,
    n_beta: usize,
    damping: DampingModel,
    free: Vec<usize>,
}

impl Variables {
    /// The variables of `model` with `damping` over `n_modes` retained modes.
    pub fn new(
        model: &StructuralModel,
        damping: DampingModel,
        n_modes: usize,
        config: &VariablesConfig,
    ) -> Result<Self> {
        let mut vars = default_variables(model, damping, n_modes, config);
        apply_overrides(&mut vars, config)?;
        for v in &vars {
            if v.fixed.is_none() {
                v.check_bounds()?;
            }
        }
        let free = (0..vars.len())
            .filter(|&i| vars[i].fixed.is_none())
            .collect::<Vec<_>>();
        if free.is_empty() {
            return Err(Error::Usage(
                "every variable is fixed: nothing to update".into(),
            ));
        }
        Ok(Variables {
            vars,
            n_alpha: model.n_alpha(),
            n_beta: model.n_beta(),
            damping,
            free,
        })
    }

    /// All variables in `theta` order.
    pub fn variables(&self) -> &[Variable] {
        &self.vars
    }
    /// Length of `theta`.
    pub fn len(&self) -> usize {
        self.vars.len()
    }
    /// Never true (a problem has at least one free variable).
    pub fn is_empty(&self) -> bool {
        self.vars.is_empty()
    }
    /// Indices (into `theta`) of the free variables, in `z` order.
    pub fn free(&self) -> &[usize] {
        &self.free
    }
    /// Names in `theta` order.
    pub fn names(&self) -> Vec<&str> {
        self.vars.iter().map(|v| v.name.as_str()).collect()
    }
    /// The damping model.
    pub fn damping_model(&self) -> DampingModel {
        self.damping
    }
    /// Number of stiffness multipliers.
    pub fn n_alpha(&self) -> usize {
        self.n_alpha
    }
    /// Number of mass multipliers.
    pub fn n_beta(&self) -> usize {
        self.n_beta
    }

    /// Start values (fixed values for fixed variables).
    pub fn initial(&self) -> Vec<f64> {
        self.vars
            .iter()
            .map(|v| v.fixed.unwrap_or(v.initial))
            .collect()
    }

    /// Splits `theta` into `(alpha, beta, damping)`.
    pub fn split<'a>(&self, theta: &'a [f64]) -> (&'a [f64], &'a [f64], Damping) {
        let (alpha, rest) = theta.split_at(self.n_alpha);
        let (beta, d) = rest.split_at(self.n_beta);
        let damping = match self.damping {
            DampingModel::Rayleigh => Damping::Rayleigh {
                a0_per_s: d[0],
                a1_s: d[1],
            },
            DampingModel::Caughey => Damping::Caughey { xi: d.to_vec() },
        };
        (alpha, beta, damping)
    }

    /// Internal vector `z` (free variables, internal scale) of `theta`.
    pub fn to_internal(&self, theta: &[f64]) -> Vec<f64> {
        self.free
            .iter()
            .map(|&i| match self.vars[i].scale {
                Scale::Linear => theta[i],
                Scale::Log => theta[i].ln(),
            })
            .collect()
    }

    /// Fills `theta` (full layout) from the internal vector `z`.
    pub fn from_internal(&self, z: &[f64], theta: &mut [f64]) {
        for (v, t) in self.vars.iter().zip(theta.iter_mut()) {
            if let Some(x) = v.fixed {
                *t = x;
            }
        }
        for (&i, &zi) in self.free.iter().zip(z) {
            theta[i] = match self.vars[i].scale {
                Scale::Linear => zi,
                Scale::Log => zi.exp(),
            };
        }
    }

    /// `theta` of an internal vector.
    pub fn theta(&self, z: &[f64]) -> Vec<f64> {
        let mut theta = vec![0.0; self.len()];
        self.from_internal(z, &mut theta);
        theta
    }

    /// `d theta_i / d z` for each free variable (1, or `theta_i` on a log scale).
    pub fn chain_factors(&self, theta: &[f64], out: &mut [f64]) {
        for (o, &i) in out.iter_mut().zip(&self.free) {
            *o = match self.vars[i].scale {
                Scale::Linear => 1.0,
                Scale::Log => theta[i],
            };
        }
    }

    /// The box of the internal vector.
    pub fn internal_bounds(&self) -> Bounds {
        let map = |i: usize, x: f64| match self.vars[i].scale {
            Scale::Linear => x,
            Scale::Log => x.ln(),
        };
        let lower = self
            .free
            .iter()
            .map(|&i| map(i, self.vars[i].lower))
            .collect();
        let upper = self
            .free
            .iter()
            .map(|&i| map(i, self.vars[i].upper))
            .collect();
        Bounds::new(lower, upper).expect("bounds validated in Variables::new")
    }

    /// Physical values for reporting (the paper's tables): story stiffness
    /// `k_r0 (1 + alpha_r)` in N/m and floor mass `m_r0 (1 + beta_r)` in kg where the
    /// model gives nominal values (the multiplier itself otherwise), damping as is.
    pub fn physical(&self, model: &StructuralModel, theta: &[f64]) -> Vec<f64> {
        let (alpha, beta, _) = self.split(theta);
        let (k, m) = model.physical_values(alpha, beta);
        k.into_iter()
            .zip(alpha)
            .chain(m.into_iter().zip(beta))
            .map(|(p, &x)| p.unwrap_or(x))
            .chain(theta[self.n_alpha + self.n_beta..].iter().copied())
            .collect()
    }

    /// Units of [`Self::physical`].
    pub fn physical_units(&self, model: &StructuralModel) -> Vec<String> {
        let params = model
            .alpha_parameters()
            .iter()
            .chain(model.beta_parameters());
        params
            .map(|p| {
                if p.nominal.is_some() {
                    p.unit.clone()
                } else {
                    "1".into()
                }
            })
            .chain(
                self.vars[self.n_alpha + self.n_beta..]
                    .iter()
                    .map(|v| v.unit.clone()),
            )
            .collect()
    }
}

/// The variables in `theta` order (alpha, beta, then damping) with the configured
/// default bounds and start values, before per-name overrides.
fn default_variables(
    model: &StructuralModel,
    damping: DampingModel,
    n_modes: usize,
    config: &VariablesConfig,
) -> Vec<Variable> {
    let damping_scale = if config.log_damping {
        Scale::Log
    } else {
        Scale::Linear
    };
    let mut vars = Vec::new();
    let mut push = |name: String, unit: &str, kind, b: [f64; 2], initial: f64, scale| {
        vars.push(Variable {
            name,
            unit: unit.into(),
            kind,
            lower: b[0],
            upper: b[1],
            initial,
            scale,
            fixed: None,
        })
    };
    for (r, p) in model.alpha_parameters().iter().enumerate() {
        push(
            p.name.clone(),
            "1",
            VariableKind::Alpha(r),
            config.alpha,
            0.0,
            Scale::Linear,
        );
    }
    for (r, p) in model.beta_parameters().iter().enumerate() {
        push(
            p.name.clone(),
            "1",
            VariableKind::Beta(r),
            config.beta,
            0.0,
            Scale::Linear,
        );
    }
    match damping {
        DampingModel::Rayleigh => {
            let c = config;
            push(
                "a0".into(),
                "1/s",
                VariableKind::A0,
                c.a0_per_s,
                c.initial_a0_per_s,
                damping_scale,
            );
            push(
                "a1".into(),
                "s",
                VariableKind::A1,
                c.a1_s,
                c.initial_a1_s,
                damping_scale,
            );
        }
        DampingModel::Caughey => {
            for i in 0..n_modes {
                push(
                    format!("xi{}", i + 1),
                    "1",
                    VariableKind::Xi(i),
                    config.xi,
                    config.initial_xi,
                    damping_scale,
                );
            }
        }
    }
    vars
}

/// The per-name bounds, start values and fixed values of `config` applied to `vars`;
/// an unknown name or an inadmissible fixed value is a usage error.
fn apply_overrides(vars: &mut [Variable], config: &VariablesConfig) -> Result<()> {
    let names: Vec<String> = vars.iter().map(|v| v.name.clone()).collect();
    let find = |name: &str, what: &str| {
        names.iter().position(|n| n == name).ok_or_else(|| {
            Error::Usage(format!(
                "{what}: no variable named '{name}'; the variables are {}",
                names.join(", ")
            ))
        })
    };
    for (name, b) in &config.bounds {
        let i = find(name, "bounds")?;
        vars[i].lower = b[0];
        vars[i].upper = b[1];
    }
    for (name, &v) in &config.initial {
        vars[find(name, "initial")?].initial = v;
    }
    for (name, &v) in &config.fixed {
        let i = find(name, "fixed")?;
        if !v.is_finite()
            || (matches!(
                vars[i].kind,
                VariableKind::A0 | VariableKind::A1 | VariableKind::Xi(_)
            ) && v < 0.0)
        {
            return Err(Error::Usage(format!(
                "fixed value {v} of {name} is not admissible"
            )));
        }
        vars[i].fixed = Some(v);
    }
    Ok(())
}

impl Variable {
    /// A free variable's bounds are finite and ordered, positive on a log scale, and
    /// hold its start value.
    fn check_bounds(&self) -> Result<()> {
        let v = self;
        if !(v.lower.is_finite() && v.upper.is_finite() && v.lower < v.upper) {
            return Err(Error::Usage(format!(
                "bounds of {} must be finite with lower < upper, got [{}, {}]",
                v.name, v.lower, v.upper
            )));
        }
        if v.scale == Scale::Log && v.lower <= 0.0 {
            return Err(Error::Usage(format!(
                "{} is optimised on a log scale, so its lower bound must be positive (got {}); \
                 raise it or set log_damping = false",
                v.name, v.lower
            )));
        }
        if !(v.initial >= v.lower && v.initial <= v.upper) {
            return Err(Error::Usage(format!(
                "start value {} of {} is outside its bounds [{}, {}]",
                v.initial, v.name, v.lower, v.upper
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> StructuralModel {
        StructuralModel::shear_frame(&[4.64; 4], &[1019.0, 1217.0, 1420.0, 2473.0]).unwrap()
    }

    #[test]
    fn layout_and_round_trip() {
        let model = frame();
        let v = Variables::new(
            &model,
            DampingModel::Caughey,
            4,
            &VariablesConfig::default(),
        )
        .unwrap();
        assert_eq!(
            v.names(),
            ["k1", "k2", "k3", "k4", "m1", "m2", "m3", "m4", "xi1", "xi2", "xi3", "xi4"]
        );
        let theta = vec![
            0.1, -0.1, 0.0, 0.2, 0.05, 0.0, -0.05, 0.1, 0.01, 0.02, 0.005, 0.001,
        ];
        let z = v.to_internal(&theta);
        assert!((z[8] - 0.01_f64.ln()).abs() < 1e-15);
        let back = v.theta(&z);
        for (a, b) in back.iter().zip(&theta) {
            assert!((a - b).abs() <= 1e-15 * b.abs().max(1.0));
        }
        let phys = v.physical(&model, &theta);
        assert!((phys[0] - 1019.0 * 1.1).abs() < 1e-9 && (phys[4] - 4.64 * 1.05).abs() < 1e-12);
        assert_eq!(phys[9], 0.02);
        let (alpha, beta, d) = v.split(&theta);
        assert_eq!((alpha.len(), beta.len()), (4, 4));
        assert_eq!(
            d,
            Damping::Caughey {
                xi: theta[8..].to_vec()
            }
        );
    }

    #[test]
    fn fixed_overrides_and_errors() {
        let model = frame();
        let mut c = VariablesConfig::default();
        c.fixed.insert("m1".into(), 0.05);
        c.bounds.insert("a1".into(), [1e-9, 1e-4]);
        let v = Variables::new(&model, DampingModel::Rayleigh, 4, &c).unwrap();
        assert_eq!(v.len(), 10);
        assert_eq!(v.free().len(), 9);
        let b = v.internal_bounds();
        assert!((b.lower()[8] - 1e-9_f64.ln()).abs() < 1e-12);
        let theta = v.theta(&v.to_internal(&v.initial()));
        assert_eq!(theta[4], 0.05);
        let mut bad = VariablesConfig::default();
        bad.fixed.insert("m9".into(), 0.0);
        let e = Variables::new(&model, DampingModel::Rayleigh, 4, &bad).unwrap_err();
        assert!(e.to_string().contains("no variable named 'm9'"), "{e}");
        let bad = VariablesConfig {
            xi: [0.0, 0.1],
            ..Default::default()
        };
        let e = Variables::new(&model, DampingModel::Caughey, 4, &bad).unwrap_err();
        assert!(e.to_string().contains("log scale"), "{e}");
        let bad = VariablesConfig {
            initial_xi: 0.5,
            ..Default::default()
        };
        assert!(Variables::new(&model, DampingModel::Caughey, 4, &bad).is_err());
        let linear = VariablesConfig {
            log_damping: false,
            xi: [0.0, 0.1],
            ..Default::default()
        };
        assert!(Variables::new(&model, DampingModel::Caughey, 4, &linear).is_ok());
    }
}
