//! Time-domain forward model of the actual tests, for hypotheses whose FRFs depend on
//! the excitation (a cubic story spring): the equivalent linearisation of
//! [`super::hypotheses`] is fast enough to sample and to compare evidence, but one
//! linear spring per segment cannot reproduce a hammer response whose frequency glides
//! as it decays. This model replays each test instead.
//!
//! For every test behind the data: the frame ([`frame_system`]) with the hypothesis'
//! linear change ([`Hypothesis::modify_system`]) and its nonlinear elements
//! ([`Hypothesis::cubic_springs`]) is driven by the *recorded* input as the estimator
//! sees it (a hammer's force inside the estimator's force windows, its offset removed;
//! a shake table's ground acceleration less its mean) and
//! stepped at the recording's sample interval ([`NonlinearFoh`]: the input is the
//! straight line between its samples, the spring forces a cubic Hermite interpolant,
//! fourth order). The simulated responses replace the recorded ones, and each segment
//! is cut and estimated exactly as the data were ([`SegmentSource`]: same slice, same
//! estimator settings, same bins), so the model's ratios carry the same windowing,
//! leakage and amplitude history as the measured ones. The model is noise-free; the
//! recorded input's noise inside the windows drives it as it drove nothing in the real
//! structure, which does not bias H1 (the ratio to that same input) of a linear frame.
//! With a cubic spring the ratio depends on the drive's level, which that noise moves
//! (by the segment's input-gain error, [`super::input_noise`]): the likelihood carries
//! it through the gain carrier [`TimeDomainModel::gain_carrier`].
//!
//! The recording stands for a band-limited signal. The stepping drives the state with
//! the straight line between pre-emphasised samples ([`crate::simulate::pre_emphasised`]),
//! whose gain against that signal is [`hold_gain`], about `1 - (omega h)^4 / 90`; each
//! ratio's state part `H - D` (`D` the channel's feedthrough, the accelerance's `1 / m`
//! at a driving point) is divided by it. [`TimeDomainModel::oversampled`] steps `r`
//! times finer on the input's band-limited (FFT) interpolation
//! ([`upsampled`]) and reads every `r`-th sample, for a replay whose own error is far
//! below the estimator's it is meant to measure.

use super::data::DiagnosisData;
use super::forward::{frame_system, BaseParams};
use super::hypothesis::Hypothesis;
use super::location::Location;
use crate::error::{Error, Result};
use crate::frf::FrfKind;
use crate::io::{Campaign, Quantity, Test, TestKind};
use crate::signal::{estimate_h1, windowed_force, EstimateOptions};
use crate::simulate::discrete::{Drive, Response};
use crate::simulate::{hold_gain, LinearSystem, NonlinearFoh};
use num_complex::Complex64;
use rayon::prelude::*;
use realfft::RealFftPlanner;
use std::sync::Arc;

/// Where a segment's record was cut from its test, and how it was estimated.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentSource {
    /// First sample of the slice in the test record.
    pub lo: usize,
    /// One past the last sample of the slice.
    pub hi: usize,
    /// The estimator's settings for the slice.
    pub estimate: EstimateOptions,
    /// Bin of the estimate behind each of the segment's frequencies.
    pub bins: Vec<usize>,
}

impl SegmentSource {
    /// A slice `[lo, hi)` estimated with `estimate` (bins set once they are selected).
    pub fn new(lo: usize, hi: usize, estimate: EstimateOptions) -> Self {
        SegmentSource {
            lo,
            hi,
            estimate,
            bins: Vec::new(),
        }
    }
}

impl Default for SegmentSource {
    fn default() -> Self {
        SegmentSource::new(0, 0, EstimateOptions::default())
    }
}

/// The time-domain model of a [`DiagnosisData`] (module docs).
#[derive(Debug, Clone)]
pub struct TimeDomainModel {
    data: Arc<DiagnosisData>,
    /// The records of the tests behind the data, in order of first use, with the
    /// estimator settings of their first segment (the force window of a hammer test).
    tests: Vec<(Test, EstimateOptions)>,
    /// Index into `tests` of each segment's record.
    test_of: Vec<usize>,
    /// Steps per sample interval of the records.
    oversampling: usize,
}

/// A test replayed: the record with its responses replaced, and each channel's
/// feedthrough `D` (0 for the input channel).
struct Replayed {
    record: Test,
    feedthrough: Vec<f64>,
}

impl TimeDomainModel {
    /// Takes the records of `data`'s tests from `campaign` (the campaign `data` was
    /// made from). Errors if a test is missing or a segment's slice does not fit it.
    pub fn new(campaign: &Campaign, data: Arc<DiagnosisData>) -> Result<Self> {
        let mut tests: Vec<(Test, EstimateOptions)> = Vec::new();
        let mut test_of = Vec::with_capacity(data.segments.len());
        for seg in &data.segments {
            let i = match tests.iter().position(|(t, _)| t.name == seg.test) {
                Some(i) => i,
                None => {
                    let t = campaign
                        .tests
                        .iter()
                        .find(|t| t.name == seg.test)
                        .ok_or_else(|| {
                            Error::Usage(format!(
                                "segment {} needs test {}, which is not in the campaign",
                                seg.name, seg.test
                            ))
                        })?;
                    tests.push((t.clone(), seg.source.estimate));
                    tests.len() - 1
                }
            };
            let src = &seg.source;
            let n_samples = tests[i].0.n_samples();
            if !(src.lo < src.hi && src.hi <= n_samples) {
                return Err(Error::Usage(format!(
                    "segment {} is samples {}..{} of a record of {}",
                    seg.name, src.lo, src.hi, n_samples
                )));
            }
            if src.bins.len() != seg.freq_hz.len() {
                return Err(Error::Usage(format!(
                    "segment {} has {} frequencies but {} estimator bins",
                    seg.name,
                    seg.freq_hz.len(),
                    src.bins.len()
                )));
            }
            test_of.push(i);
        }
        Ok(TimeDomainModel {
            data,
            tests,
            test_of,
            oversampling: 1,
        })
    }

    /// The same model stepped `r` times per sample interval on the inputs' band-limited
    /// interpolation (module docs); `r = 1` steps at the records' own rate.
    pub fn oversampled(mut self, r: usize) -> Self {
        self.oversampling = r.max(1);
        self
    }

    /// The data.
    pub fn data(&self) -> &Arc<DiagnosisData> {
        &self.data
    }

    /// Predicted ratios (flat layout, as [`super::forward::ExtendedModel::predict`]) of
    /// the frame `base` with `hypothesis` at `loc` (`effect`: physical values).
    pub fn predict(
        &self,
        base: &BaseParams,
        hypothesis: Option<(&dyn Hypothesis, &Location)>,
        effect: &[f64],
    ) -> Result<Vec<Complex64>> {
        let (sys, springs) = self.system(base, hypothesis, effect)?;
        self.predict_driven(&sys, &springs, 1.0)
    }

    /// What the input-gain error of a hammer segment multiplies in the replayed ratios
    /// (the gain carrier of [`super::data::GainCarrier::ModelAtMap`]), or `None` where it
    /// is the prediction itself (no cubic spring). The recorded force is `F (1 - delta)`
    /// for the true `F`: the measured ratio is `H[F] (1 + delta)` to first order, and the
    /// replay, driven by the recorded force, misses the drive's own error. For a linear
    /// frame `H[F]` does not depend on the drive and the carrier is `H`; with a cubic
    /// spring the ratio depends on the drive's level `s`, and the carrier is
    /// `d(s R(s)) / ds = R + dR/ds` at `s = 1` (`s R(s)` the ratio of the response to `s`
    /// times the recorded force over the recorded force, by central differences). A
    /// gain error smooth over the band ([`super::input_noise`]) scales the drift of each
    /// mode by its value near that mode, which is the scaling differentiated here.
    /// Without it the noise of the recorded force moves the cubic spring's size with no
    /// trace in its posterior: over 8 noise seeds of the benchmark's first cubic case, 1
    /// of 8 intervals of `k3` covered the truth (rms z 7.6; docs/diagnose.md).
    pub fn gain_carrier(
        &self,
        base: &BaseParams,
        hypothesis: Option<(&dyn Hypothesis, &Location)>,
        effect: &[f64],
    ) -> Result<Option<Vec<Complex64>>> {
        const STEP: f64 = 1e-3;
        let (sys, springs) = self.system(base, hypothesis, effect)?;
        if springs.iter().all(|s| s.k3_n_per_m3 == 0.0) {
            return Ok(None);
        }
        let up = self.predict_driven(&sys, &springs, 1.0 + STEP)?;
        let down = self.predict_driven(&sys, &springs, 1.0 - STEP)?;
        Ok(Some(
            up.iter()
                .zip(&down)
                .map(|(a, b)| (a - b) / (2.0 * STEP))
                .collect(),
        ))
    }

    /// The frame with the hypothesis' linear change, and its cubic springs.
    fn system(
        &self,
        base: &BaseParams,
        hypothesis: Option<(&dyn Hypothesis, &Location)>,
        effect: &[f64],
    ) -> Result<(LinearSystem, Vec<crate::simulate::CubicSpring>)> {
        let mut sys = frame_system(&self.data.model, base)?;
        let springs = match hypothesis {
            Some((h, loc)) => {
                h.modify_system(loc, effect, &mut sys)?;
                h.cubic_springs(loc, effect, &sys)?
            }
            None => Vec::new(),
        };
        Ok((sys, springs))
    }

    /// The ratios of the responses of `sys` to `drive_scale` times each recorded input,
    /// estimated against the recorded input itself.
    fn predict_driven(
        &self,
        sys: &LinearSystem,
        springs: &[crate::simulate::CubicSpring],
        drive_scale: f64,
    ) -> Result<Vec<Complex64>> {
        let r = self.oversampling;
        let records: Vec<Replayed> = self
            .tests
            .par_iter()
            .map(|(t, est)| replay(t, est, sys, springs, r, drive_scale))
            .collect::<Result<_>>()?;
        let per_segment: Vec<Vec<Complex64>> = self
            .data
            .segments
            .par_iter()
            .zip(&self.test_of)
            .map(|(seg, &ti)| {
                let src = &seg.source;
                let Replayed {
                    record: rec,
                    feedthrough,
                } = &records[ti];
                let h_s = 1.0 / (rec.sample_rate_hz * r as f64);
                let slice = Test {
                    name: rec.name.clone(),
                    kind: rec.kind,
                    sample_rate_hz: rec.sample_rate_hz,
                    channels: rec.channels.clone(),
                    data: rec
                        .data
                        .iter()
                        .map(|d| d[src.lo..src.hi].to_vec())
                        .collect(),
                };
                let h1 = estimate_h1(&slice, &src.estimate)?;
                let mut out = Vec::with_capacity(seg.n_points());
                for ch in &seg.channels {
                    let d = rec
                        .channels
                        .iter()
                        .position(|c| c.name == ch.channel.name)
                        .map_or(0.0, |i| feedthrough[i]);
                    let (_, resp) = h1
                        .iter()
                        .find(|(c, _)| c.name == ch.channel.name)
                        .ok_or_else(|| {
                            Error::Numerical(format!(
                                "replayed {} has no estimate for {}",
                                seg.name, ch.channel.name
                            ))
                        })?;
                    let plus_one = seg.is_ground() && ch.kind == FrfKind::Accelerance;
                    for &fi in &ch.freq_index {
                        let h = *resp.get(src.bins[fi]).ok_or_else(|| {
                            Error::Numerical(format!(
                                "replayed {} has fewer bins than the data",
                                seg.name
                            ))
                        })?;
                        let omega_rad_s = 2.0 * std::f64::consts::PI * seg.freq_hz[fi];
                        let h = d + (h - d) / hold_gain(omega_rad_s, h_s);
                        out.push(if plus_one { h + 1.0 } else { h });
                    }
                }
                Ok(out)
            })
            .collect::<Result<_>>()?;
        Ok(per_segment.concat())
    }
}

/// Largest relative error `1 - hold_gain` of the replay's straight-line hold of the
/// pre-emphasised input at the top of the analysed band, at which its estimator bias is
/// used: 1 %, the estimates' typical random error. At the replay's step (the records'
/// interval over [`super::estimator_bias::REPLAY_OVERSAMPLING`]) it is 6e-8 on the
/// four-story campaign (23.2 Hz at 500 Hz), 6e-5 on the bridge recorded at 60 Hz
/// (15.5 Hz) and 7e-4 on the six-DOF network (48 Hz at 100 Hz); at the records' own
/// interval 8e-5, 6 % and 0.42.
pub const HOLD_REL_ERR: f64 = 1e-2;

/// The hold error `1 - hold_gain(2 pi f, h / steps_per_sample)` at the highest analysed
/// frequency `f` of `data`, for the coarsest sample interval `h` of `campaign`'s hammer
/// tests (0 without hammer tests), and that frequency.
pub fn hold_rel_err(
    campaign: &Campaign,
    data: &DiagnosisData,
    steps_per_sample: usize,
) -> (f64, f64) {
    let f_max_hz = data
        .segments
        .iter()
        .filter(|s| !s.is_ground())
        .filter_map(|s| s.freq_hz.last().copied())
        .fold(0.0, f64::max);
    let err = campaign
        .tests
        .iter()
        .filter(|t| matches!(t.kind, TestKind::Hammer { .. }))
        .map(|t| {
            let h_s = 1.0 / (t.sample_rate_hz * steps_per_sample.max(1) as f64);
            1.0 - hold_gain(2.0 * std::f64::consts::PI * f_max_hz, h_s)
        })
        .fold(0.0, f64::max);
    (err, f_max_hz)
}

/// `test` with its response channels replaced by the responses of `sys` (with
/// `springs`) to `drive_scale` times its recorded input as the estimator `est` sees it
/// (its input channel left as recorded), from rest: a
/// hammer's force inside its force windows ([`windowed_force`]), a shake table's
/// ground acceleration less its mean; stepped `r` times per sample interval on the
/// input's band-limited interpolation.
fn replay(
    test: &Test,
    est: &EstimateOptions,
    sys: &LinearSystem,
    springs: &[crate::simulate::CubicSpring],
    r: usize,
    drive_scale: f64,
) -> Result<Replayed> {
    let (input_index, drive) = match test.kind {
        TestKind::Hammer { excited_floor } => (
            test.find(Quantity::Force),
            Drive::Force {
                dof: sys.dof_of_floor(excited_floor)?,
            },
        ),
        TestKind::ShakeTable => (test.find(Quantity::GroundAcceleration), Drive::Ground),
    };
    let input_index = input_index
        .ok_or_else(|| Error::Usage(format!("test {} has no input channel", test.name)))?;
    let u = &test.data[input_index];
    let mut input: Vec<f64> = match test.kind {
        TestKind::Hammer { .. } => windowed_force(u, test.sample_rate_hz, &est.hammer),
        TestKind::ShakeTable => {
            let mean = u.iter().sum::<f64>() / u.len().max(1) as f64;
            u.iter().map(|v| v - mean).collect()
        }
    };
    if drive_scale != 1.0 {
        input.iter_mut().for_each(|v| *v *= drive_scale);
    }
    let mut responses = Vec::new();
    let mut columns = Vec::new();
    for (i, c) in test.channels.iter().enumerate() {
        let r = match c.quantity {
            Quantity::Displacement => Response::Displacement {
                dof: sys.dof_of_floor(c.floor)?,
            },
            Quantity::Acceleration => Response::Acceleration {
                dof: sys.dof_of_floor(c.floor)?,
            },
            Quantity::Force | Quantity::GroundAcceleration => continue,
        };
        responses.push(r);
        columns.push(i);
    }
    let h_s = 1.0 / (test.sample_rate_hz * r as f64);
    let foh = NonlinearFoh::new(sys, &[drive], springs, h_s)?;
    let outputs = foh.state_space.output_map(&responses)?;
    let input = upsampled(&input, r)?;
    let y = foh.simulate(&outputs, &[input], None, &|_| {})?;
    let mut record = test.clone();
    let mut feedthrough = vec![0.0; test.channels.len()];
    for (row, (col, series)) in columns.into_iter().zip(y).enumerate() {
        record.data[col] = series.into_iter().step_by(r).collect();
        feedthrough[col] = outputs.d[(row, 0)];
    }
    Ok(Replayed {
        record,
        feedthrough,
    })
}

/// The band-limited interpolation of `u` at `r` times its rate: its spectrum (taken as
/// periodic) zero-padded, so sample `k r` of the result is `u_k` to rounding.
pub fn upsampled(u: &[f64], r: usize) -> Result<Vec<f64>> {
    let n = u.len();
    if r <= 1 || n < 2 {
        return Ok(u.to_vec());
    }
    let fft_err = |e: realfft::FftError| Error::Numerical(format!("upsampling the input: {e}"));
    let mut planner = RealFftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let mut x = u.to_vec();
    let mut spec = forward.make_output_vec();
    forward.process(&mut x, &mut spec).map_err(fft_err)?;
    let inverse = planner.plan_fft_inverse(n * r);
    let mut padded = inverse.make_input_vec();
    padded[..spec.len()].copy_from_slice(&spec);
    if n.is_multiple_of(2) {
        // The Nyquist bin stands for +-n/2 alike: half of it at each.
        padded[n / 2] *= 0.5;
    }
    let mut out = inverse.make_output_vec();
    inverse.process(&mut padded, &mut out).map_err(fft_err)?;
    Ok(out.iter().map(|v| v / n as f64).collect())
}

#[cfg(test)]
mod tests {
    use super::upsampled;

    #[test]
    fn upsampling_keeps_the_samples_and_interpolates_a_band_limited_signal() {
        let n = 64;
        let r = 4;
        // A Nyquist-frequency term too (n even): its interpolant is cos(pi t).
        let pi = std::f64::consts::PI;
        let f = |t: f64| {
            (2.0 * pi * 3.0 * t / n as f64).sin() + 0.5
                - 0.3 * (2.0 * pi * 7.0 * t / n as f64).cos()
                + 0.2 * (pi * t).cos()
        };
        let u: Vec<f64> = (0..n).map(|k| f(k as f64)).collect();
        let up = upsampled(&u, r).unwrap();
        assert_eq!(up.len(), n * r);
        for (m, v) in up.iter().enumerate() {
            let exact = f(m as f64 / r as f64);
            assert!((v - exact).abs() < 1e-12, "sample {m}: {v} against {exact}");
        }
    }
}
