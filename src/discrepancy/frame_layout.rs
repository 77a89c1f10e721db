//! Where the nominal model's parameters sit in a [`super::ModelPosterior`]'s `z`.

use super::data::DiagnosisData;
use std::ops::Range;

/// Where the nominal model's parameters sit at the front of `z`: one `ln (1 + alpha_r)`
/// per stiffness group, one `ln (1 + beta_r)` per mass group, one `ln xi` per mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameLayout {
    pub n_stiffness: usize,
    pub n_mass: usize,
    pub n_xi: usize,
}

impl FrameLayout {
    /// The layout of `data`'s model: its groups, and a damping ratio for each of its
    /// modes in the analysed band (`nominal_freq_hz`: every mode of a model that is not
    /// reduced; the modes above share the last ratio, [`super::forward::frame_system`]).
    pub fn of(data: &DiagnosisData) -> Self {
        FrameLayout {
            n_stiffness: data.model.n_alpha(),
            n_mass: data.model.n_beta(),
            n_xi: data.nominal_freq_hz.len(),
        }
    }
    /// Indices of the stiffness scales.
    pub fn stiffness(&self) -> Range<usize> {
        0..self.n_stiffness
    }
    /// Indices of the mass scales.
    pub fn mass(&self) -> Range<usize> {
        self.n_stiffness..self.n_stiffness + self.n_mass
    }
    /// Indices of the damping ratios.
    pub fn xi(&self) -> Range<usize> {
        let start = self.n_stiffness + self.n_mass;
        start..start + self.n_xi
    }
}
