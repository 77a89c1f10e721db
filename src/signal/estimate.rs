//! FRF estimates of whole tests and campaigns, and their hand-over to model updating.

use super::bands::{select_bands, Band, BandOptions};
use super::hammer::{hammer_spectra, HammerOptions, Impact};
use super::input_noise::InputNoise;
use super::local_coherence::LocalModel;
use super::noise::{pooled_rel_std, CoherenceMethod};
use super::spectra::{bin_freq_hz, CrossSpectra};
use super::sweep::full_record_spectra;
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
    /// The input's windowed spectrum of each block at every bin (empty for estimates read
    /// from files): what the correlation of the estimate's errors between bins needs
    /// besides the window ([`Self::input_turn`]).
    pub input_spectra: Vec<Vec<Complex64>>,
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
    /// `g_kl = sum_b conj(F_bk) F_bl / sqrt(P_k P_l)` over the blocks' input spectra `F_b`
    /// (`P` the input power): what the input adds to the correlation of the H1 errors of
    /// bins `k` and `l`, `E[e_k conj(e_l)] / (sd_k sd_l) = c(k - l) g_kl / (H_k conj(H_l))`
    /// (`|e| / |H|`) for output noise of window correlation `c`. One block gives
    /// `exp(-j (phi_k - phi_l))`, the turn of the input's phase: a hammer record with two
    /// impacts `t` s apart wobbles by up to `2 asin(a)` between bins (`a` the second
    /// impact's windowed amplitude relative to the first). 1 without the spectra.
    pub fn input_turn(&self, k: usize, l: usize) -> Complex64 {
        let g: Complex64 = self
            .input_spectra
            .iter()
            .filter_map(|f| Some(f.get(k)?.conj() * f.get(l)?))
            .sum();
        let p = (self.input_power.get(k).copied().unwrap_or(0.0)
            * self.input_power.get(l).copied().unwrap_or(0.0))
        .sqrt();
        match self.input_spectra.is_empty() || !(p > 0.0 && g.is_finite()) {
            true => Complex64::new(1.0, 0.0),
            false => g / p,
        }
    }

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
        self.responses
            .iter()
            .flat_map(|r| self.selected.iter().map(move |&k| r.h1[k].norm()))
            .collect()
    }

    /// Bendat & Piersol relative standard deviation of `|H1|` at the selected points, same
    /// order as [`Self::selected_magnitudes`].
    pub fn selected_rel_std(&self) -> Vec<f64> {
        self.selected_pooled_rel_std(false, 0)
    }

    /// [`Self::selected_rel_std`] of the output noise alone (from `output_coherence`).
    pub fn selected_output_rel_std(&self) -> Vec<f64> {
        self.selected_pooled_rel_std(true, 0)
    }

    /// The Bendat & Piersol relative sd at the selected points from the coherence
    /// (`output` false) or the output coherence (true), with the noise's auto-spectrum
    /// pooled over `+-half_width` bins ([`pooled_rel_std`]; 0: each bin's own).
    pub fn selected_pooled_rel_std(&self, output: bool, half_width: usize) -> Vec<f64> {
        self.responses
            .iter()
            .flat_map(|r| {
                let coherence = if output {
                    &r.output_coherence
                } else {
                    &r.coherence
                };
                pooled_rel_std(
                    &r.h1,
                    coherence,
                    &self.input_power,
                    self.n_averages,
                    half_width,
                    &self.selected,
                )
            })
            .collect()
    }

    /// The bands and selected bins this test's estimate would have if its responses'
    /// magnitudes were `magnitudes` (one curve per response, in response order, on
    /// `freq_hz`): the same search ([`select_bands`]; the test's input power and
    /// coherence decide where) on another curve, e.g. the fitted model's FRFs
    /// (`crate::bayes`, two-stage selection: their peak bins and -3 dB points do not
    /// lean on the noise of the bins they select). Replaces `bands` and `selected`.
    pub fn reselect_on(
        &mut self,
        magnitudes: &[Vec<f64>],
        opts: &BandOptions,
        n_peaks: usize,
    ) -> Result<()> {
        let n = self.freq_hz.len();
        if magnitudes.len() != self.responses.len() || magnitudes.iter().any(|m| m.len() != n) {
            return Err(Error::Usage(format!(
                "test {}: band reselection needs {} curves of {n} bins",
                self.test,
                self.responses.len()
            )));
        }
        let curves: Vec<Vec<Complex64>> = magnitudes
            .iter()
            .map(|m| m.iter().map(|&v| Complex64::new(v, 0.0)).collect())
            .collect();
        let refs: Vec<&[Complex64]> = curves.iter().map(Vec::as_slice).collect();
        let (bands, selected) = bands_on(
            &self.freq_hz,
            &self.responses,
            &refs,
            &self.input_power,
            opts,
            n_peaks,
        )?;
        self.bands = bands;
        self.selected = selected;
        Ok(())
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
    let freq_hz = kept_freq_hz(n_fft, fs, opts.freq_max_hz);
    let n_keep = freq_hz.len();
    let n_blocks = f_blocks.len();
    let local = match opts.coherence {
        CoherenceMethod::Ordinary => None,
        CoherenceMethod::LocalRational { half_width_bins } => Some(
            LocalModel::new(half_width_bins, tau, block_len, fs, n_fft, n_keep, n_blocks)
                .map_err(|e| Error::invalid(&path, e.to_string()))?,
        ),
    };
    let coherence_dof = match &local {
        None => n_blocks,
        Some(l) => l.dof.effective.round().max(1.0) as usize,
    };
    use rayon::prelude::*;
    let responses = resp_idx
        .par_iter()
        .zip(y_blocks.par_iter())
        .map(|(&ci, yb)| {
            estimate_response(
                &test.channels[ci],
                &f_blocks,
                yb,
                local.as_ref(),
                &input_noise,
                n_keep,
            )
        })
        .collect::<Result<Vec<_>>>()
        .map_err(|e| Error::invalid(&path, e.to_string()))?;
    let input_power = input_power(&f_blocks, n_keep);
    let input_spectra: Vec<Vec<Complex64>> =
        f_blocks.iter().map(|f| f[..n_keep].to_vec()).collect();
    let input_noise = (local.is_some() && input_noise_weights.iter().any(|w| !w.is_empty()))
        .then(|| InputNoise::new(n_fft, input_noise_weights, input_spectra.clone()))
        .transpose()
        .map_err(|e| Error::invalid(&path, e.to_string()))?;
    let (bands, selected) = test_bands(&freq_hz, &responses, &input_power, opts)?;
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
        input_spectra,
        bands,
        selected,
        input_noise,
    })
}

/// The relative error the input channel's noise puts on every response of a shake-table
/// test at once, `E|delta_k|^2` with `delta_k = -N_x / X_k` ([`super::common_input`]), at
/// the bins `bins` of [`estimate_test`]'s grid (NaN where it cannot be estimated); empty
/// for other tests, fewer than two responses or the ordinary coherence. Part of the
/// coherence. Computed on demand (the diagnosis asks for its selected bins only).
pub fn common_input_rel_var(
    test: &Test,
    opts: &EstimateOptions,
    bins: &[usize],
) -> Result<Vec<f64>> {
    let local_coherence = matches!(opts.coherence, CoherenceMethod::LocalRational { .. });
    if test.kind != TestKind::ShakeTable || !local_coherence {
        return Ok(Vec::new());
    }
    let (b, resp_idx) = test_blocks(test, opts)?;
    if resp_idx.len() < 2 || b.f_blocks.len() != 1 {
        return Ok(Vec::new());
    }
    let fs = test.sample_rate_hz;
    let n_fft = b.block_len * opts.zero_pad_factor.max(1);
    let n_keep = kept_freq_hz(n_fft, fs, opts.freq_max_hz).len();
    let m = super::common_input::HALF_WIDTH_BINS;
    let Ok(local) = LocalModel::new(m, b.tau, b.block_len, fs, n_fft, n_keep, 1) else {
        return Ok(Vec::new());
    };
    let rec = super::common_input::RecordSpectra {
        x: &b.f_blocks[0],
        y: b.y_blocks.iter().map(|yb| yb[0].as_slice()).collect(),
        absolute: resp_idx
            .iter()
            .map(|&i| test.channels[i].quantity == Quantity::Acceleration)
            .collect(),
    };
    Ok(super::common_input::common_input_rel_var(
        &local, &rec, bins,
    ))
}

/// Bin frequencies (Hz) of `n_fft`-point spectra at `fs_hz`, up to `freq_max_hz`
/// (`None`: up to Nyquist).
fn kept_freq_hz(n_fft: usize, fs_hz: f64, freq_max_hz: Option<f64>) -> Vec<f64> {
    let mut freq_hz = bin_freq_hz(n_fft, fs_hz);
    let n_keep = match freq_max_hz {
        Some(fmax) => freq_hz.iter().take_while(|&&f| f <= fmax).count(),
        None => freq_hz.len(),
    };
    freq_hz.truncate(n_keep);
    freq_hz
}

/// H1, H2 and coherences of one response channel from the input and response spectra per
/// block, on the first `n_keep` bins: ordinary coherence, or that of the `local` models
/// (with the smooth input noise `input_noise` per block).
fn estimate_response(
    channel: &Channel,
    f_blocks: &[Vec<Complex64>],
    y_blocks: &[Vec<Complex64>],
    local: Option<&LocalModel>,
    input_noise: &[f64],
    n_keep: usize,
) -> Result<ResponseFrf> {
    let channel = channel.clone();
    let kind = kind_of(channel.quantity)
        .ok_or_else(|| Error::Usage(format!("channel {} is not a response", channel.name)))?;
    let spectra = CrossSpectra::from_blocks(f_blocks, y_blocks)?;
    let h1 = spectra.h1();
    let (mut coherence, mut output_coherence) = match local {
        None => {
            let c = spectra.ordinary_coherence();
            (c.clone(), c)
        }
        Some(local) => local.coherences(f_blocks, y_blocks, &h1, &spectra, input_noise)?,
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
}

/// Input auto-spectrum summed over blocks (unnormalised, windowed) on the first `n_keep`
/// bins.
fn input_power(f_blocks: &[Vec<Complex64>], n_keep: usize) -> Vec<f64> {
    let mut input_power = vec![0.0; n_keep];
    for fb in f_blocks {
        for (p, f) in input_power.iter_mut().zip(fb) {
            *p += f.norm_sqr();
        }
    }
    input_power
}

/// Resonance bands and selected bins of a test from its responses' H1 and mean
/// coherence; as many peaks as `opts.bands.n_peaks`, else as the highest floor measured.
fn test_bands(
    freq_hz: &[f64],
    responses: &[ResponseFrf],
    input_power: &[f64],
    opts: &EstimateOptions,
) -> Result<(Vec<Band>, Vec<usize>)> {
    let n_peaks = opts
        .bands
        .n_peaks
        .unwrap_or_else(|| responses.iter().map(|r| r.channel.floor).max().unwrap_or(0));
    let h_refs: Vec<&[Complex64]> = responses.iter().map(|r| r.h1.as_slice()).collect();
    bands_on(
        freq_hz,
        responses,
        &h_refs,
        input_power,
        &opts.bands,
        n_peaks,
    )
}

/// [`select_bands`] on `curves` (one per response, on the grid), searching where the
/// responses' mean coherence and the input power allow.
fn bands_on(
    freq_hz: &[f64],
    responses: &[ResponseFrf],
    curves: &[&[Complex64]],
    input_power: &[f64],
    opts: &BandOptions,
    n_peaks: usize,
) -> Result<(Vec<Band>, Vec<usize>)> {
    let mean_coherence: Vec<f64> = (0..freq_hz.len())
        .map(|k| responses.iter().map(|r| r.coherence[k]).sum::<f64>() / responses.len() as f64)
        .collect();
    select_bands(freq_hz, curves, input_power, &mean_coherence, opts, n_peaks)
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
mod tests;
