//! FRF estimates of whole tests and campaigns, and their hand-over to model updating.

use super::bands::{select_bands, Band, BandOptions};
use super::correlation::{NoiseWindow, WindowDof};
use super::hammer::{hammer_spectra, HammerOptions, Impact};
use super::input_noise::InputNoise;
use super::noise::{
    add_smooth_input_noise, bendat_piersol_rel_std, local_rational_noise, CoherenceMethod,
};
use super::spectra::{bin_freq_hz, CrossSpectra};
use super::sweep::full_record_spectra;
use super::windows::exponential_window;
use crate::error::{Error, Result};
use crate::frf::{Excitation, FrfBlock, FrfKind, FrfPair};
use crate::io::{Campaign, Channel, Quantity, Test, TestKind};
use num_complex::Complex64;
use std::path::{Path, PathBuf};

/// Options of [`estimate_test`] / [`estimate_campaign`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EstimateOptions {
    /// Impact detection, blocks and windows (hammer tests).
    pub hammer: HammerOptions,
    /// How coherence is estimated.
    pub coherence: CoherenceMethod,
    /// Peak and half-power band selection.
    pub bands: BandOptions,
    /// Zero padding: `n_fft = zero_pad_factor x block length` (1 = none). Padding adds no
    /// information; it interpolates the spectrum of the (windowed) block.
    pub zero_pad_factor: usize,
    /// Keep bins up to this frequency, Hz (`None`: up to Nyquist).
    pub freq_max_hz: Option<f64>,
}

impl Default for EstimateOptions {
    fn default() -> Self {
        EstimateOptions {
            hammer: HammerOptions::default(),
            coherence: CoherenceMethod::default(),
            bands: BandOptions::default(),
            zero_pad_factor: 1,
            freq_max_hz: None,
        }
    }
}

/// What drives a test.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InputKind {
    /// Impact force at `floor` (1-based), channel `channel`, N.
    Force { floor: usize, channel: String },
    /// Ground (shake-table) acceleration, channel `channel`, m/s^2. Responses are relative
    /// to the ground (Eq. 14).
    Ground { channel: String },
}

impl InputKind {
    /// The excitation of the analytic FRF (0-based DOF).
    pub fn excitation(&self) -> Result<Excitation> {
        match self {
            InputKind::Force { floor, .. } if *floor >= 1 => Ok(Excitation::Dof(floor - 1)),
            InputKind::Force { floor, .. } => Err(Error::Usage(format!(
                "force at floor {floor}: the ground is not a DOF of the model"
            ))),
            InputKind::Ground { .. } => Ok(Excitation::Ground),
        }
    }
}

/// The estimate for one response channel.
#[derive(Debug, Clone, PartialEq)]
pub struct ResponseFrf {
    pub channel: Channel,
    /// Accelerance for acceleration channels (relative to the ground in shake-table tests),
    /// receptance for displacement channels.
    pub kind: FrfKind,
    /// H1 at every bin (m/N, m/s^2/N, m/(m/s^2) or (m/s^2)/(m/s^2)).
    pub h1: Vec<Complex64>,
    /// H2 at every bin (equal to H1 with one block).
    pub h2: Vec<Complex64>,
    /// Coherence gamma^2 at every bin (see [`CoherenceMethod`]).
    pub coherence: Vec<f64>,
    /// The coherence of the output noise alone, without the smooth force noise that
    /// [`TestFrf::input_noise`] describes (equal to `coherence` when there is none).
    pub output_coherence: Vec<f64>,
}

impl ResponseFrf {
    /// The analytic FRF pair this estimate corresponds to.
    pub fn pair(&self, input: &InputKind) -> Result<FrfPair> {
        if self.channel.floor == 0 {
            return Err(Error::Usage(format!(
                "channel {} is on the ground, not a DOF of the model",
                self.channel.name
            )));
        }
        Ok(FrfPair {
            response: self.channel.floor - 1,
            excitation: input.excitation()?,
            kind: self.kind,
        })
    }
}

/// FRF estimate of one test.
#[derive(Debug, Clone, PartialEq)]
pub struct TestFrf {
    /// Test (folder) name.
    pub test: String,
    /// Bin frequencies, Hz (`k fs / n_fft`, from 0).
    pub freq_hz: Vec<f64>,
    pub input: InputKind,
    /// Responses in channel order.
    pub responses: Vec<ResponseFrf>,
    /// Number of blocks averaged in H1 (1 for a whole-record estimate, hammer or shake
    /// table; the impacts with [`super::HammerEstimator::ImpactBlocks`]): the `n` of the
    /// Bendat & Piersol random error.
    pub n_averages: usize,
    /// Effective complex degrees of freedom behind each coherence value (local models:
    /// `n_averages (2m + 1) - 3` for independent bins, fewer for the correlated bins of an
    /// exponential window, see [`super::correlation`]; ordinary coherence: `n_averages`).
    pub coherence_dof: usize,
    /// Exponential window time constant, s, if one was applied: the estimate is then
    /// `H(omega - j / tau)` (see [`super::windows`]).
    pub exp_window_tau_s: Option<f64>,
    /// Block (record) duration, s; the frequency resolution is `1 / block_s` before padding.
    pub block_s: f64,
    /// Impact times used, s from the record start (hammer tests).
    pub impacts_s: Vec<f64>,
    /// Input auto-spectrum summed over blocks (unnormalised, windowed), per bin.
    pub input_power: Vec<f64>,
    /// Resonance bands, ascending in frequency.
    pub bands: Vec<Band>,
    /// Selected bins (indices into `freq_hz`, ascending).
    pub selected: Vec<usize>,
    /// The force noise inside the force windows (hammer tests with force window): an
    /// error of `|H1|` smooth in frequency and common to all responses ([`InputNoise`]);
    /// it is part of `coherence`, not of `output_coherence`.
    pub input_noise: Option<InputNoise>,
}

impl TestFrf {
    /// The response called `name`.
    pub fn response(&self, name: &str) -> Option<&ResponseFrf> {
        self.responses.iter().find(|r| r.channel.name == name)
    }

    /// Analytic FRF pairs of the responses, in response order.
    pub fn pairs(&self) -> Result<Vec<FrfPair>> {
        self.responses.iter().map(|r| r.pair(&self.input)).collect()
    }

    /// The block (selected frequencies in rad/s, all pairs) for [`crate::frf::ModalFrf`].
    pub fn frf_block(&self) -> Result<FrfBlock> {
        Ok(FrfBlock {
            omega_rad_s: self
                .selected
                .iter()
                .map(|&k| 2.0 * std::f64::consts::PI * self.freq_hz[k])
                .collect(),
            pairs: self.pairs()?,
        })
    }

    /// Experimental `|H1|` at the selected points, in the long-vector order of
    /// [`Self::frf_block`] (pair, then frequency; Eqs. 17-19).
    pub fn selected_magnitudes(&self) -> Vec<f64> {
        self.selected_map(|r, k| r.h1[k].norm())
    }

    /// Bendat & Piersol relative standard deviation of `|H1|` at the selected points, same
    /// order as [`Self::selected_magnitudes`].
    pub fn selected_rel_std(&self) -> Vec<f64> {
        let n = self.n_averages;
        self.selected_map(|r, k| bendat_piersol_rel_std(r.coherence[k], n))
    }

    /// [`Self::selected_rel_std`] of the output noise alone (from `output_coherence`).
    pub fn selected_output_rel_std(&self) -> Vec<f64> {
        let n = self.n_averages;
        self.selected_map(|r, k| bendat_piersol_rel_std(r.output_coherence[k], n))
    }

    fn selected_map(&self, f: impl Fn(&ResponseFrf, usize) -> f64) -> Vec<f64> {
        self.responses
            .iter()
            .flat_map(|r| self.selected.iter().map(move |&k| (r, k)))
            .map(|(r, k)| f(r, k))
            .collect()
    }
}

/// Block spectra of a test, before the estimators.
struct Blocks {
    input: InputKind,
    /// Input spectra per block.
    f_blocks: Vec<Vec<Complex64>>,
    /// Per block, input noise power per bin that the local model cannot see.
    input_noise: Vec<f64>,
    /// Per block, the force noise sample by sample ([`InputNoise::weights`]).
    input_noise_weights: Vec<Vec<(usize, f64)>>,
    /// Per response, spectra per block.
    y_blocks: Vec<Vec<Vec<Complex64>>>,
    tau: Option<f64>,
    /// Block length, samples (before padding).
    block_len: usize,
    impacts: Vec<Impact>,
}

fn data_path(test: &Test) -> PathBuf {
    Path::new("tests").join(&test.name).join("data.csv")
}

fn kind_of(quantity: Quantity) -> Option<FrfKind> {
    match quantity {
        Quantity::Acceleration => Some(FrfKind::Accelerance),
        Quantity::Displacement => Some(FrfKind::Receptance),
        _ => None,
    }
}

/// Checks `test` and transforms its blocks (the part of [`estimate_test`] before the
/// estimators); also the indices of its response channels.
fn test_blocks(test: &Test, opts: &EstimateOptions) -> Result<(Blocks, Vec<usize>)> {
    let path = data_path(test);
    if test.sample_rate_hz.is_nan() || test.sample_rate_hz <= 0.0 {
        return Err(Error::invalid(path, "sample rate must be positive"));
    }
    if test.data.len() != test.channels.len() {
        return Err(Error::invalid(path, "one data column per channel required"));
    }
    let resp_idx = test.response_channels();
    if resp_idx.is_empty() {
        return Err(Error::invalid(
            path,
            "no acceleration or displacement channel",
        ));
    }
    let pad = opts.zero_pad_factor.max(1);
    let fs = test.sample_rate_hz;
    let blocks = match test.kind {
        TestKind::Hammer { excited_floor } => {
            let fi = test
                .find(Quantity::Force)
                .ok_or_else(|| Error::invalid(&path, "hammer test without a force channel"))?;
            let records: Vec<&[f64]> = resp_idx.iter().map(|&i| test.data[i].as_slice()).collect();
            let s = hammer_spectra(&test.data[fi], &records, fs, &opts.hammer, pad)
                .map_err(|e| Error::invalid(&path, e.to_string()))?;
            let input = InputKind::Force {
                floor: excited_floor,
                channel: test.channels[fi].name.clone(),
            };
            Blocks {
                input,
                f_blocks: s.force,
                input_noise: s.force_noise_power,
                input_noise_weights: s.force_noise_weights,
                y_blocks: s.responses,
                tau: s.tau_s,
                block_len: s.len,
                impacts: s.impacts,
            }
        }
        TestKind::ShakeTable => {
            let gi = test.find(Quantity::GroundAcceleration).ok_or_else(|| {
                Error::invalid(
                    &path,
                    "shake-table test without a ground_acceleration channel",
                )
            })?;
            let ground = &test.data[gi];
            let records: Vec<Vec<f64>> = resp_idx
                .iter()
                .map(|&i| match test.channels[i].quantity {
                    Quantity::Acceleration => test.data[i]
                        .iter()
                        .zip(ground)
                        .map(|(a, g)| a - g)
                        .collect(),
                    _ => test.data[i].clone(),
                })
                .collect();
            let refs: Vec<&[f64]> = records.iter().map(Vec::as_slice).collect();
            let s = full_record_spectra(ground, &refs, pad)
                .map_err(|e| Error::invalid(&path, e.to_string()))?;
            let input = InputKind::Ground {
                channel: test.channels[gi].name.clone(),
            };
            let y = s.responses.into_iter().map(|r| vec![r]).collect();
            Blocks {
                input,
                f_blocks: vec![s.input],
                input_noise: vec![0.0],
                input_noise_weights: vec![Vec::new()],
                y_blocks: y,
                tau: None,
                block_len: test.n_samples(),
                impacts: Vec::new(),
            }
        }
    };
    Ok((blocks, resp_idx))
}

/// H1 alone of every response channel of `test` (in channel order), at every bin of
/// [`estimate_test`] from 0 Hz (same blocks, windows and padding; no coherence, no
/// bands, no truncation): what a model replay of a recorded test needs.
pub fn estimate_h1(test: &Test, opts: &EstimateOptions) -> Result<Vec<(Channel, Vec<Complex64>)>> {
    let (blocks, resp_idx) = test_blocks(test, opts)?;
    resp_idx
        .iter()
        .zip(&blocks.y_blocks)
        .map(|(&ci, yb)| {
            let spectra = CrossSpectra::from_blocks(&blocks.f_blocks, yb)?;
            Ok((test.channels[ci].clone(), spectra.h1()))
        })
        .collect::<Result<Vec<_>>>()
        .map_err(|e| Error::invalid(data_path(test), e.to_string()))
}

/// Estimates the FRFs of one test: hammer tests by the whole-record transient or impact
/// blocks ([`super::hammer`]), shake-table tests by the full-record transform
/// ([`super::sweep`]) with accelerations made relative to the ground. `n_peaks` for band
/// selection falls back to the highest floor among the response channels.
pub fn estimate_test(test: &Test, opts: &EstimateOptions) -> Result<TestFrf> {
    let path = data_path(test);
    let pad = opts.zero_pad_factor.max(1);
    let fs = test.sample_rate_hz;
    let (
        Blocks {
            input,
            f_blocks,
            input_noise,
            input_noise_weights,
            y_blocks,
            tau,
            block_len,
            impacts,
        },
        resp_idx,
    ) = test_blocks(test, opts)?;
    let n_fft = block_len * pad;
    let mut freq_hz = bin_freq_hz(n_fft, fs);
    let n_keep = match opts.freq_max_hz {
        Some(fmax) => freq_hz.iter().take_while(|&&f| f <= fmax).count(),
        None => freq_hz.len(),
    };
    freq_hz.truncate(n_keep);
    let n_blocks = f_blocks.len();
    // local models: bins spaced so that the noise of neighbours is at most 50 % correlated
    // (exponential window, zero padding), the rest normalised exactly ([`super::correlation`])
    let local = match opts.coherence {
        CoherenceMethod::Ordinary => None,
        CoherenceMethod::LocalRational { half_width_bins } => {
            let expw = tau.map(|t| exponential_window(block_len, 1.0 / fs, t));
            let window = NoiseWindow::new(expw.as_deref(), block_len, n_fft)
                .map_err(|e| Error::invalid(&path, e.to_string()))?;
            let step = window.decorrelating_step();
            let corr = window.window_correlation(half_width_bins, step);
            let dof = WindowDof::new(Some(&corr), half_width_bins, n_blocks)
                .map_err(|e| Error::invalid(&path, e.to_string()))?;
            // bins the windows of the kept bins reach
            let n_local = (n_keep + 2 * half_width_bins * step).min(n_fft / 2 + 1);
            Some((half_width_bins, step, corr, dof, n_local))
        }
    };
    let coherence_dof = match &local {
        None => n_blocks,
        Some((_, _, _, dof, _)) => dof.effective.round().max(1.0) as usize,
    };
    use rayon::prelude::*;
    let responses = resp_idx
        .par_iter()
        .zip(y_blocks.par_iter())
        .map(|(&ci, yb)| {
            let channel = test.channels[ci].clone();
            let kind = kind_of(channel.quantity).ok_or_else(|| {
                Error::Usage(format!("channel {} is not a response", channel.name))
            })?;
            let spectra = CrossSpectra::from_blocks(&f_blocks, yb)?;
            let h1 = spectra.h1();
            let (mut coherence, mut output_coherence) = match &local {
                None => {
                    let c = spectra.ordinary_coherence();
                    (c.clone(), c)
                }
                Some((half_width, step, corr, _, n_local)) => {
                    let cut = |b: &[Vec<Complex64>]| -> Vec<Vec<Complex64>> {
                        b.iter().map(|v| v[..*n_local].to_vec()).collect()
                    };
                    let fb = cut(&f_blocks);
                    let mut noise = local_rational_noise(
                        &fb,
                        &cut(yb),
                        &h1[..*n_local],
                        *half_width,
                        *step,
                        Some(corr),
                    )?;
                    let mut out = noise.coherence.clone();
                    add_smooth_input_noise(&mut noise, &h1, &fb, &input_noise)?;
                    let mut c = noise.coherence;
                    for ((v, o), null) in c.iter_mut().zip(&mut out).zip(spectra.null_input()) {
                        if null {
                            *v = 0.0;
                            *o = 0.0;
                        }
                    }
                    (c, out)
                }
            };
            let mut h1 = h1;
            let mut h2 = spectra.h2();
            h1.truncate(n_keep);
            h2.truncate(n_keep);
            coherence.truncate(n_keep);
            output_coherence.truncate(n_keep);
            Ok(ResponseFrf {
                channel,
                kind,
                h1,
                h2,
                coherence,
                output_coherence,
            })
        })
        .collect::<Result<Vec<_>>>()
        .map_err(|e| Error::invalid(&path, e.to_string()))?;
    let mut input_power = vec![0.0; n_keep];
    for fb in &f_blocks {
        for (p, f) in input_power.iter_mut().zip(fb) {
            *p += f.norm_sqr();
        }
    }
    let input_noise = (local.is_some() && input_noise_weights.iter().any(|w| !w.is_empty()))
        .then(|| {
            let force = f_blocks.iter().map(|f| f[..n_keep].to_vec()).collect();
            InputNoise::new(n_fft, input_noise_weights, force)
        })
        .transpose()
        .map_err(|e| Error::invalid(&path, e.to_string()))?;
    let n_peaks = opts
        .bands
        .n_peaks
        .unwrap_or_else(|| responses.iter().map(|r| r.channel.floor).max().unwrap_or(0));
    let h_refs: Vec<&[Complex64]> = responses.iter().map(|r| r.h1.as_slice()).collect();
    let mean_coherence: Vec<f64> = (0..n_keep)
        .map(|k| responses.iter().map(|r| r.coherence[k]).sum::<f64>() / responses.len() as f64)
        .collect();
    let (bands, selected) = select_bands(
        &freq_hz,
        &h_refs,
        &input_power,
        &mean_coherence,
        &opts.bands,
        n_peaks,
    )?;
    Ok(TestFrf {
        test: test.name.clone(),
        freq_hz,
        input,
        responses,
        n_averages: n_blocks,
        coherence_dof,
        exp_window_tau_s: tau,
        block_s: block_len as f64 / fs,
        impacts_s: impacts.iter().map(|p| p.trigger as f64 / fs).collect(),
        input_power,
        bands,
        selected,
        input_noise,
    })
}

/// Estimates every test of a campaign (in test order). `n_peaks` defaults to the number of
/// floors of the nominal model (as many peaks as the model has modes).
pub fn estimate_campaign(campaign: &Campaign, opts: &EstimateOptions) -> Result<Vec<TestFrf>> {
    let mut opts = *opts;
    if opts.bands.n_peaks.is_none() {
        opts.bands.n_peaks = Some(campaign.nominal.n_floors());
    }
    campaign
        .tests
        .iter()
        .map(|t| {
            estimate_test(t, &opts).map_err(|e| match e {
                Error::Invalid { path, what } => Error::invalid(campaign.root.join(path), what),
                other => other,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::NominalModel;

    fn channel(name: &str, quantity: Quantity, floor: usize) -> Channel {
        Channel {
            name: name.into(),
            quantity,
            floor,
            unit: quantity.unit().into(),
        }
    }

    /// A damped oscillation "response" to a pulse: enough for the error paths.
    fn record(n: usize) -> (Vec<f64>, Vec<f64>) {
        let mut f = vec![0.0; n];
        f[100] = 10.0;
        f[101] = 5.0;
        let y = (0..n)
            .map(|i| {
                let t = i.saturating_sub(100) as f64 * 0.01;
                if i < 100 {
                    0.0
                } else {
                    (-0.5 * t).exp() * (6.0 * t).sin()
                }
            })
            .collect();
        (f, y)
    }

    fn hammer(channels: Vec<Channel>, data: Vec<Vec<f64>>) -> Test {
        Test {
            name: "h".into(),
            kind: TestKind::Hammer { excited_floor: 1 },
            sample_rate_hz: 100.0,
            channels,
            data,
        }
    }

    #[test]
    fn estimate_test_errors_name_the_file_and_the_problem() {
        let (f, y) = record(4000);
        let no_force = hammer(
            vec![channel("acc1", Quantity::Acceleration, 1)],
            vec![y.clone()],
        );
        let e = estimate_test(&no_force, &EstimateOptions::default()).unwrap_err();
        assert!(e.to_string().contains("tests/h/data.csv") && e.to_string().contains("force"));
        let no_resp = hammer(vec![channel("force", Quantity::Force, 1)], vec![f.clone()]);
        assert!(estimate_test(&no_resp, &EstimateOptions::default()).is_err());
        let mut shake = hammer(
            vec![channel("acc1", Quantity::Acceleration, 1)],
            vec![y.clone()],
        );
        shake.kind = TestKind::ShakeTable;
        let e = estimate_test(&shake, &EstimateOptions::default()).unwrap_err();
        assert!(e.to_string().contains("ground_acceleration"));
        let quiet = hammer(
            vec![
                channel("force", Quantity::Force, 1),
                channel("acc1", Quantity::Acceleration, 1),
            ],
            vec![vec![0.0; 4000], y.clone()],
        );
        let e = estimate_test(&quiet, &EstimateOptions::default()).unwrap_err();
        assert!(e.to_string().contains("no impact"));
        let mut bad_rate = quiet.clone();
        bad_rate.sample_rate_hz = 0.0;
        assert!(estimate_test(&bad_rate, &EstimateOptions::default()).is_err());
    }

    #[test]
    fn campaign_defaults_peaks_to_floors_and_prefixes_root() {
        let (f, y) = record(4000);
        let test = hammer(
            vec![
                channel("force", Quantity::Force, 1),
                channel("acc1", Quantity::Acceleration, 1),
                channel("disp1", Quantity::Displacement, 1),
            ],
            vec![f, y.clone(), y],
        );
        let campaign = Campaign {
            root: PathBuf::from("/data/c"),
            title: "t".into(),
            nominal: NominalModel::shear_frame(vec![1.0], vec![1.0]),
            tests: vec![test.clone()],
            warnings: Vec::new(),
        };
        let est = estimate_campaign(&campaign, &EstimateOptions::default()).unwrap();
        assert_eq!(est.len(), 1);
        let e = &est[0];
        assert_eq!(e.bands.len(), 1);
        assert!((e.bands[0].peak_hz - 6.0 / (2.0 * std::f64::consts::PI)).abs() < 0.02);
        assert_eq!(
            e.input,
            InputKind::Force {
                floor: 1,
                channel: "force".into()
            }
        );
        let pairs = e.pairs().unwrap();
        assert_eq!(pairs[0].kind, FrfKind::Accelerance);
        assert_eq!(pairs[1].kind, FrfKind::Receptance);
        assert_eq!(pairs[0].excitation, Excitation::Dof(0));
        let block = e.frf_block().unwrap();
        assert_eq!(block.omega_rad_s.len(), e.selected.len());
        let mags = e.selected_magnitudes();
        assert_eq!(mags.len(), 2 * e.selected.len());
        assert_eq!(mags[0], e.responses[0].h1[e.selected[0]].norm());
        assert_eq!(e.selected_rel_std().len(), mags.len());
        let mut broken = campaign;
        broken.tests[0].data[0] = vec![0.0; 4000];
        let err = estimate_campaign(&broken, &EstimateOptions::default()).unwrap_err();
        assert!(
            err.to_string().starts_with("/data/c/tests/h/data.csv"),
            "{err}"
        );
    }
}
