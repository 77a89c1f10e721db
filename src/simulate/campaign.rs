//! From a [`SimModel`] to a [`Campaign`]: one test at a time, each one input series
//! through the exact discretisation, then every channel through its sensor chain.

use super::antialias::Decimator;
use super::config::{SimModel, StructureSpec, TestSpec};
use super::discrete::{Drive, Foh, Response, StateSpace};
use super::effects::EffectSpec;
use super::excitation::{Chirp, Excitation, HalfSinePulses};
use super::modal_basis::ModalBasis;
use super::nonlinear::{CubicSpring, NonlinearFoh};
use super::sensor::{noise_stream, run_chain, Decimate, GaussianNoise, SensorStage, Signal};
use super::system::LinearSystem;
use crate::error::{Error, Result};
use crate::io::{write_atomic, Campaign, Channel, Quantity, Test, TestKind};
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// One channel to record: what it is, what it reads, and its sensor chain.
#[derive(Debug, Clone)]
pub struct ChannelPlan {
    pub channel: Channel,
    pub response: Response,
    pub stages: Vec<Arc<dyn SensorStage>>,
}

/// A ready-to-run simulator: the true system, the anti-aliasing filter, the tests.
#[derive(Debug)]
pub struct Simulator {
    model: SimModel,
    system: LinearSystem,
    springs: Vec<CubicSpring>,
    decimator: Arc<Decimator>,
    /// The truncated modal basis a general structure is simulated in.
    basis: Option<ModalBasis>,
}

impl Simulator {
    /// Builds the true system (structure, damping, then the model's effects in order),
    /// its cubic springs (resolved on the final system), and the anti-aliasing filter.
    /// The model is validated again (errors name `<model>`).
    pub fn new(model: SimModel) -> Result<Self> {
        model.validate(Path::new("<model>"))?;
        let system = LinearSystem::from_spec(&model.structure, &model.damping)?
            .with_effects(&model.effects)?;
        let s = &model.sampling;
        let (springs, basis) = match &model.structure {
            StructureSpec::ShearFrame {
                story_stiffness_n_per_m,
                ..
            } => {
                let springs = model
                    .effects
                    .iter()
                    .filter_map(|e| match e {
                        EffectSpec::StiffnessNonlinearity(s) => {
                            Some(s.spring(&system, story_stiffness_n_per_m[s.story - 1]))
                        }
                        _ => None,
                    })
                    .collect::<Result<Vec<_>>>()?;
                (springs, None)
            }
            StructureSpec::General {
                modal_cutoff_hz, ..
            } => {
                let cutoff_hz = modal_cutoff_hz.unwrap_or(0.5 * s.internal_rate_hz());
                (Vec::new(), Some(ModalBasis::new(&system, cutoff_hz)?))
            }
        };
        let decimator = Decimator::kaiser(
            s.internal_rate_hz(),
            s.oversampling,
            s.passband_fraction * 0.5 * s.output_rate_hz,
            0.5 * s.output_rate_hz,
            s.stopband_attenuation_db,
        )?;
        Ok(Simulator {
            model,
            system,
            springs,
            decimator: Arc::new(decimator),
            basis,
        })
    }

    /// The truncated modal basis of a general structure (`None` for a shear frame, which
    /// is simulated in physical coordinates).
    pub fn modal_basis(&self) -> Option<&ModalBasis> {
        self.basis.as_ref()
    }

    /// The model.
    pub fn model(&self) -> &SimModel {
        &self.model
    }

    /// The simulated system (the truth; the linearisation when there are cubic springs).
    pub fn system(&self) -> &LinearSystem {
        &self.system
    }

    /// Cubic springs of the truth (empty for a linear system).
    pub fn cubic_springs(&self) -> &[CubicSpring] {
        &self.springs
    }

    /// The anti-aliasing filter.
    pub fn decimator(&self) -> &Decimator {
        &self.decimator
    }

    /// Samples written for `test`.
    pub fn n_output_samples(&self, test: &TestSpec) -> usize {
        (test.duration_s() * self.model.sampling.output_rate_hz).round() as usize
    }

    /// Internal samples simulated for `test`: the record plus half the filter length plus
    /// what the sensor effects read ahead, so that every record is exact to its end.
    pub fn n_internal_samples(&self, test: &TestSpec) -> usize {
        let rate_hz = self.model.sampling.internal_rate_hz();
        let lookahead = self
            .model
            .sensor_effects
            .iter()
            .filter(|e| e.tests().is_none_or(|t| t.iter().any(|t| t == test.name())))
            .map(|e| e.lookahead_samples(rate_hz))
            .max()
            .unwrap_or(0);
        (self.n_output_samples(test) - 1) * self.model.sampling.oversampling
            + 1
            + self.decimator.half_len()
            + lookahead
    }

    /// Units of work reported through `progress` by [`Self::run`]: per test, one per
    /// internal sample stepped and one per internal sample filtered.
    pub fn total_work(&self) -> u64 {
        self.model
            .tests
            .iter()
            .map(|t| 2 * self.n_internal_samples(t) as u64)
            .sum()
    }

    /// Simulates every test (in parallel; the result does not depend on the thread count).
    pub fn run(&self, seed: u64, progress: &(dyn Fn(u64) + Sync)) -> Result<Campaign> {
        let mut tests = self
            .model
            .tests
            .par_iter()
            .map(|t| self.simulate_test(t, seed, progress))
            .collect::<Result<Vec<_>>>()?;
        tests.sort_by(|a, b| a.name.cmp(&b.name));
        Ok(Campaign {
            root: Default::default(),
            title: self.model.title.clone(),
            nominal: self.model.nominal_model(self.system.n_floors())?,
            tests,
            warnings: Vec::new(),
        })
    }

    /// The input of `test`: where it acts and its continuous-time signal.
    pub fn excitation(&self, test: &TestSpec) -> Result<(Drive, Box<dyn Excitation>)> {
        Ok(match test {
            TestSpec::Hammer {
                excited_floor,
                pulse_duration_s,
                impacts,
                ..
            } => (
                Drive::Force {
                    dof: self.system.dof_of_floor(*excited_floor)?,
                },
                Box::new(HalfSinePulses {
                    pulse_duration_s: *pulse_duration_s,
                    impacts: impacts.clone(),
                }),
            ),
            TestSpec::ShakeTable { chirp, .. } => (Drive::Ground, Box::new(Chirp(chirp.clone()))),
        })
    }

    /// The channels of `test`, as in the real campaign: the input (`force` at the
    /// excited floor, or `ground_acc`), then `acc1..n` (absolute) and `disp1..n`
    /// (relative to the ground / table, base motion included when the base is flexible);
    /// on a general structure `acc<k>`, `disp<k>` at its sensor DOFs `k` (1-based);
    /// each with its sensor chain: the sensor effects that name
    /// it (in model order), anti-aliasing and decimation, then noise of its quantity's
    /// standard deviation (when positive).
    pub fn channels(&self, test: &TestSpec, seed: u64) -> Result<Vec<ChannelPlan>> {
        let n = self.system.n_floors();
        let mut plan: Vec<(Channel, Response)> = Vec::with_capacity(2 * n + 1);
        let ch = |name: String, quantity: Quantity, floor: usize| Channel {
            name,
            quantity,
            floor,
            unit: quantity.unit().into(),
        };
        match test {
            TestSpec::Hammer { excited_floor, .. } => plan.push((
                ch("force".into(), Quantity::Force, *excited_floor),
                Response::Input(0),
            )),
            TestSpec::ShakeTable { .. } => plan.push((
                ch("ground_acc".into(), Quantity::GroundAcceleration, 0),
                Response::Input(0),
            )),
        }
        let (acc, disp) = self.model.structure.sensors(n);
        for f in acc {
            let dof = self.system.dof_of_floor(f)?;
            plan.push((
                ch(format!("acc{f}"), Quantity::Acceleration, f),
                Response::Acceleration { dof },
            ));
        }
        for f in disp {
            let dof = self.system.dof_of_floor(f)?;
            plan.push((
                ch(format!("disp{f}"), Quantity::Displacement, f),
                Response::Displacement { dof },
            ));
        }
        let decimate: Arc<dyn SensorStage> = Arc::new(Decimate {
            decimator: self.decimator.clone(),
            n_out: self.n_output_samples(test),
        });
        let noise = &self.model.noise;
        Ok(plan
            .into_iter()
            .map(|(channel, response)| {
                let std = match channel.quantity {
                    Quantity::Force => noise.force_n,
                    Quantity::GroundAcceleration => noise.ground_acceleration_m_per_s2,
                    Quantity::Acceleration => noise.acceleration_m_per_s2,
                    Quantity::Displacement => noise.displacement_m,
                };
                let mut stages: Vec<Arc<dyn SensorStage>> = self
                    .model
                    .sensor_effects
                    .iter()
                    .filter(|e| e.applies_to(test.name(), &channel.name, channel.quantity))
                    .map(|e| Arc::new(e.clone()) as Arc<dyn SensorStage>)
                    .collect();
                stages.push(decimate.clone());
                if std > 0.0 {
                    stages.push(Arc::new(GaussianNoise {
                        std,
                        seed,
                        stream: noise_stream(test.name(), &channel.name),
                        ar1: noise.ar1_coefficient,
                    }));
                }
                ChannelPlan {
                    channel,
                    response,
                    stages,
                }
            })
            .collect())
    }

    /// Simulates one test.
    pub fn simulate_test(
        &self,
        test: &TestSpec,
        seed: u64,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Test> {
        let (drive, excitation) = self.excitation(test)?;
        let channels = self.channels(test, seed)?;
        let responses: Vec<Response> = channels.iter().map(|c| c.response).collect();
        let internal_rate_hz = self.model.sampling.internal_rate_hz();
        let n_int = self.n_internal_samples(test);
        let input = excitation.sample(internal_rate_hz, n_int);
        let raw = if let Some(basis) = &self.basis {
            let ss = basis.state_space(&[drive])?;
            let outputs = basis.output_map(&ss, &responses)?;
            let foh = Foh::new(&ss, 1.0 / internal_rate_hz)?;
            foh.simulate(&outputs, &[input], None, progress)?
        } else if self.springs.is_empty() {
            let ss = StateSpace::new(&self.system, &[drive])?;
            let outputs = ss.output_map(&responses)?;
            let foh = Foh::new(&ss, 1.0 / internal_rate_hz)?;
            foh.simulate(&outputs, &[input], None, progress)?
        } else {
            let nl = NonlinearFoh::new(
                &self.system,
                &[drive],
                &self.springs,
                1.0 / internal_rate_hz,
            )?;
            let outputs = nl.state_space.output_map(&responses)?;
            nl.simulate(&outputs, &[input], None, progress)
                .map_err(|e| match e {
                    Error::Numerical(what) => {
                        Error::Numerical(format!("test {}: {what}", test.name()))
                    }
                    e => e,
                })?
        };
        let n_ch = channels.len() as u64;
        let data = channels
            .par_iter()
            .zip(raw)
            .enumerate()
            .map(|(i, (plan, samples))| {
                let out = run_chain(
                    &plan.stages,
                    Signal {
                        samples,
                        rate_hz: internal_rate_hz,
                    },
                )?;
                // Spread the filtering work over the channels so the total is n_int.
                let share = n_int as u64 / n_ch + u64::from((i as u64) < n_int as u64 % n_ch);
                progress(share);
                Ok(out.samples)
            })
            .collect::<Result<Vec<_>>>()?;
        if data.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::Numerical(format!(
                "test {}: non-finite samples",
                test.name()
            )));
        }
        Ok(Test {
            name: test.name().to_string(),
            kind: match test {
                TestSpec::Hammer { excited_floor, .. } => TestKind::Hammer {
                    excited_floor: *excited_floor,
                },
                TestSpec::ShakeTable { .. } => TestKind::ShakeTable,
            },
            sample_rate_hz: self.model.sampling.output_rate_hz,
            channels: channels.into_iter().map(|c| c.channel).collect(),
            data,
        })
    }

    /// Writes `truth.json` into the campaign folder `root`: the model, the seed, and the
    /// true modes of the simulated system (all its DOFs, extra ones included): natural
    /// frequencies, damping ratios `(Phi^T C Phi)_ii / 2 omega_i` (exact only when
    /// `proportional_damping` is true), mass-normalised shapes at the floor DOFs; the
    /// DOF of the base when it is flexible; with cubic springs, all of this is the
    /// small-amplitude linearisation.
    ///
    /// On a general structure the shapes are given at the sensor DOFs only
    /// (`mode_shapes_at_sensor_dofs`, `sensor_dofs` 1-based), and `modal_basis` records
    /// the cutoff and the number of modes simulated.
    pub fn write_truth(&self, root: &Path, seed: u64) -> Result<()> {
        let modes = self.system.modes()?;
        let xi = self.system.modal_damping_ratios()?;
        let shape_dofs: Vec<usize> = match &self.basis {
            None => self.system.floor_dof.clone(),
            Some(_) => self.sensor_dofs().iter().map(|k| k - 1).collect(),
        };
        let shapes: Vec<Vec<f64>> = (0..modes.n_modes())
            .map(|i| shape_dofs.iter().map(|&d| modes.phi[(d, i)]).collect())
            .collect();
        let cm = modes.phi.transpose() * &self.system.damping_n_s_per_m * &modes.phi;
        let off_diagonal = (0..cm.nrows())
            .flat_map(|i| {
                (0..cm.ncols())
                    .filter(move |&j| j != i)
                    .map(move |j| (i, j))
            })
            .fold(0.0_f64, |a, (i, j)| a.max(cm[(i, j)].abs()));
        let mut truth = serde_json::json!({
            "generator": format!("frfbayes {} simulate", env!("CARGO_PKG_VERSION")),
            "seed": seed,
            "n_dof": self.system.n_dof(),
            "floor_dof": self.system.floor_dof,
            "base_dof": self.system.base_dof,
            "linear": self.springs.is_empty(),
            "natural_frequencies_hz": modes.freq_hz(),
            "damping_ratios": xi,
            "proportional_damping": off_diagonal <= 1e-9 * cm.amax(),
            "mode_shapes_at_floors": shapes,
            "model": self.model,
        });
        if let Some(basis) = self.modal_basis_info() {
            let t = &mut truth;
            t.as_object_mut().map(|o| o.remove("floor_dof"));
            t.as_object_mut().map(|o| o.remove("mode_shapes_at_floors"));
            t["sensor_dofs"] = serde_json::json!(self.sensor_dofs());
            t["mode_shapes_at_sensor_dofs"] = serde_json::json!(shapes);
            t["modal_basis"] = basis;
        }
        let text = serde_json::to_string_pretty(&truth)
            .map_err(|e| Error::Numerical(format!("truth.json: {e}")))?;
        write_atomic(&root.join("truth.json"), text.as_bytes())
    }
}

impl Simulator {
    /// Sensor locations of a general structure (1-based DOFs, ascending, each once).
    pub fn sensor_dofs(&self) -> Vec<usize> {
        let (acc, disp) = self.model.structure.sensors(self.system.n_floors());
        let mut dofs: Vec<usize> = acc.into_iter().chain(disp).collect();
        dofs.sort_unstable();
        dofs.dedup();
        dofs
    }

    /// The modal basis of a general structure as recorded in `truth.json` and `run.json`:
    /// cutoff, modes kept of all, and the highest kept natural frequency.
    pub fn modal_basis_info(&self) -> Option<serde_json::Value> {
        self.basis.as_ref().map(|b| {
            serde_json::json!({
                "cutoff_hz": b.cutoff_hz,
                "n_modes": b.n_modes(),
                "n_dof": self.system.n_dof(),
                "highest_kept_hz": b.omega_rad_s.last().map(|w| w / (2.0 * std::f64::consts::PI)),
                "rule": "every undamped mode up to cutoff_hz (default: the internal Nyquist \
                         frequency, oversampling * output_rate_hz / 2)",
            })
        })
    }
}

/// The seed to use: `override_seed` when given, else the model's `seed`.
pub fn resolve_seed(model: &SimModel, override_seed: Option<u64>, path: &Path) -> Result<u64> {
    override_seed.or(model.seed).ok_or_else(|| {
        Error::invalid(
            path,
            "no seed: set `seed = <integer>` in the model file or pass --seed",
        )
    })
}
