//! Validation of a [`SimModel`]: everything that can be checked without building
//! matrices (those are checked when the system is built). Every error names the model
//! file and the offending key.

use super::config::{channel_names, DampingSpec, SimModel, StructureSpec, TestSpec};
use super::effects::EffectSpec;
use super::sensor_effects::SensorEffect;
use crate::error::{Error, Result};
use crate::io::Quantity;
use std::path::{Path, PathBuf};

/// The error "`what` is wrong in the model file `path`".
fn bad<T>(path: &Path, what: String) -> Result<T> {
    Err(Error::invalid(path, what))
}

impl SimModel {
    /// Number of floors (shear frame) or DOFs (general model, loading its manifest),
    /// after checking the structure and the nominal model.
    fn check_structure(&self, path: &Path) -> Result<usize> {
        let bad = |what: String| Err(Error::invalid(path, what));
        let StructureSpec::ShearFrame {
            floor_mass_kg,
            story_stiffness_n_per_m,
        } = &self.structure
        else {
            if self.nominal.is_some() {
                return bad(
                    "nominal: a general structure's nominal model is its manifest (at \
                     alpha = beta = 0); remove [nominal]"
                        .into(),
                );
            }
            // A general structure's floors are its DOFs: an oscillator on a DOF and a
            // dashpot between two DOFs are defined on it; stories and the base are not.
            if let Some(i) = self.effects.iter().position(|e| !on_dofs(e)) {
                return bad(format!(
                    "effect {}: stories and the base are defined on shear frames; on a \
                     general structure use an oscillator on a DOF (floor = DOF) or a dashpot \
                     between two DOFs (floors = [a, b])",
                    i + 1
                ));
            }
            return Ok(super::general::load(&self.structure, path)?.0.n_dof());
        };
        let n = floor_mass_kg.len();
        check_shear_frame("structure", floor_mass_kg, story_stiffness_n_per_m, path)?;
        if let Some(nom) = &self.nominal {
            check_shear_frame(
                "nominal",
                &nom.floor_mass_kg,
                &nom.story_stiffness_n_per_m,
                path,
            )?;
            if nom.floor_mass_kg.len() != n {
                return bad(format!(
                    "nominal has {} floors but the structure has {n}",
                    nom.floor_mass_kg.len()
                ));
            }
        }
        Ok(n)
    }

    /// Checks everything that can be checked without building matrices (those are checked
    /// when the system is built). Errors name `path` and the offending key.
    pub fn validate(&self, path: &Path) -> Result<()> {
        let n = self.check_structure(path)?;
        self.check_damping(n, path)?;
        self.check_sampling(path)?;
        self.check_noise(path)?;
        if self.tests.is_empty() {
            return bad(path, "no [[test]] given".into());
        }
        for (i, t) in self.tests.iter().enumerate() {
            self.check_test(i, t, n, path)?;
        }
        self.check_effects(n, path)?;
        for (i, e) in self.sensor_effects.iter().enumerate() {
            self.check_sensor_effect(i, e, n, path)?;
        }
        Ok(())
    }

    /// The damping of a structure with `n` floors or DOFs: finite non-negative Rayleigh
    /// coefficients, or 1..=n finite non-negative ratios (exactly n for modal damping).
    fn check_damping(&self, n: usize, path: &Path) -> Result<()> {
        match &self.damping {
            DampingSpec::Rayleigh { a0_per_s, a1_s } => {
                if !(*a0_per_s >= 0.0 && *a1_s >= 0.0 && a0_per_s.is_finite() && a1_s.is_finite()) {
                    return bad(path, format!(
                        "damping: a0_per_s and a1_s must be finite and >= 0 (got {a0_per_s}, {a1_s})"
                    ));
                }
            }
            DampingSpec::Caughey { xi } | DampingSpec::Modal { xi } => {
                if xi.is_empty() || xi.len() > n {
                    return bad(
                        path,
                        format!("damping: give 1..={n} damping ratios xi (got {})", xi.len()),
                    );
                }
                if matches!(self.damping, DampingSpec::Modal { .. }) && xi.len() != n {
                    return bad(
                        path,
                        format!(
                            "damping: modal damping needs one ratio per mode ({n}), got {}",
                            xi.len()
                        ),
                    );
                }
                if let Some(x) = xi.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                    return bad(path, format!("damping: ratio {x} must be finite and >= 0"));
                }
            }
        }
        Ok(())
    }

    /// `[sampling]`: a positive output rate (Hz), oversampling in 1..=100, a passband
    /// fraction in (0, 1) and a stopband attenuation in [21, 200] dB.
    fn check_sampling(&self, path: &Path) -> Result<()> {
        let s = &self.sampling;
        if !(s.output_rate_hz.is_finite() && s.output_rate_hz > 0.0) {
            return bad(
                path,
                format!(
                    "sampling.output_rate_hz must be positive (got {})",
                    s.output_rate_hz
                ),
            );
        }
        if !(1..=100).contains(&s.oversampling) {
            return bad(
                path,
                format!(
                    "sampling.oversampling must be in 1..=100 (got {})",
                    s.oversampling
                ),
            );
        }
        if !(s.passband_fraction > 0.0 && s.passband_fraction < 1.0) {
            return bad(
                path,
                format!(
                    "sampling.passband_fraction must be in (0, 1) (got {})",
                    s.passband_fraction
                ),
            );
        }
        if !(s.stopband_attenuation_db >= 21.0 && s.stopband_attenuation_db <= 200.0) {
            return bad(
                path,
                format!(
                    "sampling.stopband_attenuation_db must be in [21, 200] (got {})",
                    s.stopband_attenuation_db
                ),
            );
        }
        Ok(())
    }

    /// `[noise]`: every standard deviation finite and non-negative, the AR(1)
    /// coefficient in `[0, 1)`.
    fn check_noise(&self, path: &Path) -> Result<()> {
        let z = &self.noise;
        for (key, v) in [
            ("force_n", z.force_n),
            (
                "ground_acceleration_m_per_s2",
                z.ground_acceleration_m_per_s2,
            ),
            ("acceleration_m_per_s2", z.acceleration_m_per_s2),
            ("displacement_m", z.displacement_m),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(
                    path,
                    format!("noise.{key} must be finite and >= 0 (got {v})"),
                );
            }
        }
        let phi = z.ar1_coefficient;
        if !(phi.is_finite() && (0.0..1.0).contains(&phi)) {
            return bad(
                path,
                format!("noise.ar1_coefficient must be in [0, 1) (got {phi}); 0 is white noise"),
            );
        }
        Ok(())
    }

    /// Test `i` (0-based) of a structure with `n` floors or DOFs: a plain, unique folder
    /// name, a record of at least 2 output samples, then its excitation.
    fn check_test(&self, i: usize, t: &TestSpec, n: usize, path: &Path) -> Result<()> {
        let s = &self.sampling;
        let name = t.name();
        if name.is_empty()
            || name.starts_with('.')
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
        {
            return bad(
                path,
                format!(
                    "test {}: name {name:?} must be a plain folder name (letters, digits, - _ .)",
                    i + 1
                ),
            );
        }
        if self.tests[..i].iter().any(|u| u.name() == name) {
            return bad(path, format!("test name {name:?} is used twice"));
        }
        let duration_s = t.duration_s();
        if !(duration_s.is_finite() && duration_s * s.output_rate_hz >= 2.0) {
            return bad(
                path,
                format!(
                "test {name}: the record must hold at least 2 samples (duration {duration_s} s)"
            ),
            );
        }
        match t {
            TestSpec::Hammer { .. } => self.check_hammer(t, n, path),
            TestSpec::ShakeTable { .. } => self.check_shake_table(t, path),
        }
    }

    /// A hammer test (`t`, record `duration_s` long): the excited floor in 1..=n, a pulse
    /// of at least two internal samples, and every impact inside the record with a finite
    /// peak force.
    fn check_hammer(&self, t: &TestSpec, n: usize, path: &Path) -> Result<()> {
        let TestSpec::Hammer {
            excited_floor,
            pulse_duration_s,
            impacts,
            ..
        } = t
        else {
            return Ok(());
        };
        let name = t.name();
        let duration_s = t.duration_s();
        let internal_step_s = 1.0 / self.sampling.internal_rate_hz();
        if *excited_floor == 0 || *excited_floor > n {
            return bad(
                path,
                format!("test {name}: excited_floor must be in 1..={n} (got {excited_floor})"),
            );
        }
        if !(pulse_duration_s.is_finite() && *pulse_duration_s >= 2.0 * internal_step_s) {
            return bad(path, format!(
                "test {name}: pulse_duration_s {pulse_duration_s} is shorter than two internal samples ({:e} s); raise sampling.oversampling",
                2.0 * internal_step_s
            ));
        }
        if impacts.is_empty() {
            return bad(path, format!("test {name}: no impacts"));
        }
        for imp in impacts {
            if !(imp.time_s >= 0.0 && imp.time_s + pulse_duration_s <= duration_s) {
                return bad(
                    path,
                    format!(
                    "test {name}: impact at {} s does not fit in the record [0, {duration_s}] s",
                    imp.time_s
                ),
                );
            }
            if !imp.peak_force_n.is_finite() {
                return bad(path, format!("test {name}: peak_force_n must be finite"));
            }
        }
        Ok(())
    }

    /// A shake-table test `t`: finite chirp values, frequencies in [0, output Nyquist) Hz,
    /// non-negative start and ring-down, a positive sweep and a taper of at most half of it.
    fn check_shake_table(&self, t: &TestSpec, path: &Path) -> Result<()> {
        let TestSpec::ShakeTable {
            chirp, ring_down_s, ..
        } = t
        else {
            return Ok(());
        };
        let name = t.name();
        let c = chirp;
        let nyquist_hz = 0.5 * self.sampling.output_rate_hz;
        let finite = [
            c.f0_hz,
            c.f1_hz,
            c.start_s,
            c.sweep_duration_s,
            c.taper_s,
            c.amplitude_m_per_s2,
            *ring_down_s,
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite {
            return bad(path, format!("test {name}: chirp values must be finite"));
        }
        if c.f0_hz < 0.0 || c.f1_hz < 0.0 || c.f0_hz.max(c.f1_hz) >= nyquist_hz {
            return bad(
                path,
                format!(
                "test {name}: chirp frequencies must be in [0, {nyquist_hz}) Hz (output Nyquist)"
            ),
            );
        }
        if c.start_s < 0.0 || *ring_down_s < 0.0 || c.sweep_duration_s <= 0.0 {
            return bad(
                path,
                format!("test {name}: start_s and ring_down_s must be >= 0, sweep_duration_s > 0"),
            );
        }
        if c.taper_s < 0.0 || 2.0 * c.taper_s > c.sweep_duration_s {
            return bad(
                path,
                format!("test {name}: taper_s must be in [0, sweep_duration_s / 2]"),
            );
        }
        Ok(())
    }

    /// `[[effect]]`s on a structure with `n` floors: each valid, at most one base.
    fn check_effects(&self, n: usize, path: &Path) -> Result<()> {
        for (i, e) in self.effects.iter().enumerate() {
            e.check(n)
                .or_else(|what| bad(path, format!("effect {}: {what}", i + 1)))?;
            if matches!(e, EffectSpec::BaseFlexibility(_))
                && self.effects[..i]
                    .iter()
                    .any(|f| matches!(f, EffectSpec::BaseFlexibility(_)))
            {
                return bad(
                    path,
                    format!(
                        "effect {}: base_flexibility is given twice (one base only)",
                        i + 1
                    ),
                );
            }
        }
        Ok(())
    }

    /// `[[sensor_effect]]` `i` (0-based), `e`, on a structure with `n` floors or DOFs:
    /// valid, oversampled enough for a time offset, naming existing tests, and acting on
    /// a quantity and channels that its tests record.
    fn check_sensor_effect(&self, i: usize, e: &SensorEffect, n: usize, path: &Path) -> Result<()> {
        let (acc, disp) = self.structure.sensors(n);
        e.check()
            .or_else(|what| bad(path, format!("sensor_effect {}: {what}", i + 1)))?;
        if matches!(e, SensorEffect::TimeOffset(_)) && self.sampling.oversampling < 4 {
            return bad(path, format!(
                "sensor_effect {}: a time offset needs sampling.oversampling >= 4 (band-limited interpolation)",
                i + 1
            ));
        }
        if let Some(t) = e
            .tests()
            .into_iter()
            .flatten()
            .find(|t| !self.tests.iter().any(|u| u.name() == t.as_str()))
        {
            return bad(
                path,
                format!("sensor_effect {}: no test named {t:?}", i + 1),
            );
        }
        let in_scope = || {
            self.tests.iter().filter(|t| {
                e.tests()
                    .is_none_or(|names| names.iter().any(|n| n == t.name()))
            })
        };
        if let Some(q) = e.quantity() {
            let has = |t: &TestSpec| match q {
                Quantity::Force => matches!(t, TestSpec::Hammer { .. }),
                Quantity::GroundAcceleration => matches!(t, TestSpec::ShakeTable { .. }),
                Quantity::Acceleration | Quantity::Displacement => true,
            };
            if !in_scope().any(has) {
                return bad(
                    path,
                    format!(
                        "sensor_effect {}: none of its tests records a {q:?} channel",
                        i + 1
                    ),
                );
            }
        }
        for c in e.channels() {
            let known = in_scope().any(|t| channel_names(t, &acc, &disp).iter().any(|k| k == c));
            if !known {
                return bad(path, format!(
                    "sensor_effect {}: no channel {c:?} in its tests (channels are force or ground_acc, acc1..{n}, disp1..{n})",
                    i + 1
                ));
            }
        }
        Ok(())
    }
}

/// True for an effect defined on DOFs alone (see [`SimModel::check_structure`]).
fn on_dofs(e: &EffectSpec) -> bool {
    match e {
        EffectSpec::Oscillator(_) => true,
        EffectSpec::Dashpot(d) => d.story.is_none(),
        EffectSpec::BaseFlexibility(_) | EffectSpec::StiffnessNonlinearity(_) => false,
    }
}

fn check_shear_frame(key: &str, m: &[f64], k: &[f64], path: &Path) -> Result<()> {
    let err = |what: String| Err(Error::invalid(PathBuf::from(path), what));
    if m.is_empty() || m.len() != k.len() {
        return err(format!(
            "{key}: floor_mass_kg and story_stiffness_n_per_m need the same, non-zero length (got {} and {})",
            m.len(),
            k.len()
        ));
    }
    if let Some((i, v)) = m
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v > 0.0))
    {
        return err(format!(
            "{key}: floor {} mass must be positive (got {v})",
            i + 1
        ));
    }
    if let Some((i, v)) = k
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v > 0.0))
    {
        return err(format!(
            "{key}: story {} stiffness must be positive (got {v})",
            i + 1
        ));
    }
    Ok(())
}
