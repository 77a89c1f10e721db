//! Our FRF estimates out as UFF dataset 58 (one FRF and one coherence per response),
//! with the manifest that reads them back as measured FRFs.
//!
//! Nodes: a response on floor / DOF `k` is node `k`, direction `+X`; a force on DOF `j`
//! is reference node `j`, `+X`; ground excitation is reference node 0, `+X`. Units SI:
//! receptance `m` / `N`, accelerance `m/s^2` / `N`, per ground acceleration `m/s^2`.

use super::super::estimate::{InputKind, TestFrf};
use crate::error::Result;
use crate::frf::FrfKind;
use crate::uff::{Abscissa, Axis, Function58, FunctionType, NodeDof, Ordinate, Precision};
use std::fmt::Write as _;
use std::path::Path;

fn axis(data_type: i32, length_exp: i32, force_exp: i32, label: &str, units: &str) -> Axis {
    Axis {
        data_type,
        length_exp,
        force_exp,
        temperature_exp: 0,
        label: label.into(),
        units: units.into(),
    }
}

/// The FRFs and coherences of `frf` as datasets 58 (double precision, even abscissa
/// when the grid is even to 1e-9, uneven otherwise).
pub fn test_frf_datasets(frf: &TestFrf) -> Vec<Function58> {
    let (ref_node, denominator, input_name) = match &frf.input {
        InputKind::Force { floor, channel } => {
            (*floor as i64, axis(13, 0, 1, "Force", "N"), channel)
        }
        InputKind::Ground { channel } => (0, axis(12, 1, 0, "Acceleration", "m/s^2"), channel),
    };
    let f = &frf.freq_hz;
    let step = if f.len() > 1 { f[1] - f[0] } else { 1.0 };
    let even = f
        .iter()
        .enumerate()
        .all(|(k, v)| (v - (f[0] + k as f64 * step)).abs() <= 1e-9 * v.abs().max(step));
    let abscissa = if even {
        Abscissa::Even { min: f[0], step }
    } else {
        Abscissa::Uneven(f.clone())
    };
    let mut out = Vec::new();
    for (k, r) in frf.responses.iter().enumerate() {
        let numerator = match r.kind {
            FrfKind::Receptance => axis(8, 1, 0, "Displacement", "m"),
            FrfKind::Mobility => axis(11, 1, 0, "Velocity", "m/s"),
            FrfKind::Accelerance => axis(12, 1, 0, "Acceleration", "m/s^2"),
        };
        let base = Function58 {
            id_lines: [
                format!("H1 {} / {input_name}", r.channel.name),
                frf.test.clone(),
                "NONE".into(),
                format!("frfbayes {}", env!("CARGO_PKG_VERSION")),
                "NONE".into(),
            ],
            function_type: FunctionType::Frf,
            function_id: k as i32 + 1,
            version: 0,
            load_case: 0,
            response: NodeDof {
                entity: r.channel.name.clone(),
                node: r.channel.floor as i64,
                direction: 1,
            },
            reference: NodeDof {
                entity: input_name.clone(),
                node: ref_node,
                direction: 1,
            },
            abscissa: abscissa.clone(),
            z_axis_value: 0.0,
            axes: [
                axis(18, 0, 0, "Frequency", "Hz"),
                numerator,
                denominator.clone(),
                axis(0, 0, 0, "NONE", "NONE"),
            ],
            ordinate: Ordinate::Complex(r.h1.clone()),
            precision: Precision::Double,
        };
        let mut coherence = base.clone();
        coherence.id_lines[0] = format!("Coherence {} / {input_name}", r.channel.name);
        coherence.function_type = FunctionType::Coherence;
        coherence.axes[1] = axis(0, 0, 0, "Coherence", "NONE");
        coherence.axes[2] = axis(0, 0, 0, "NONE", "NONE");
        coherence.ordinate = Ordinate::Real(r.coherence.clone());
        out.push(base);
        out.push(coherence);
    }
    out
}

/// The measured-FRF manifest (TOML text) that reads `frfs`, written as
/// `<test>/<file_name>` beside it, back against the model of the campaign at `model`.
pub fn manifest_for(frfs: &[TestFrf], model: &Path, file_name: &str) -> Result<String> {
    let q = |s: &str| toml::Value::String(s.to_string()).to_string();
    let mut m = String::from("# Measured-FRF manifest written by `frfbayes frf`; use: frfbayes sample --frfs <this file>\n");
    let _ = writeln!(m, "model = {}", q(&model.to_string_lossy()));
    for t in frfs {
        let _ = writeln!(
            m,
            "\n[[test]]\nname = {}\nfile = {}",
            q(&t.test),
            q(&format!("{}/{file_name}", t.test))
        );
        match &t.input {
            InputKind::Force { floor, .. } => {
                let _ = writeln!(
                    m,
                    "excitation = \"force\"\nexcited_dof = {floor}\nreference = \"{floor}+X\""
                );
            }
            InputKind::Ground { .. } => {
                let _ = writeln!(m, "excitation = \"ground\"\nreference = \"0+X\"");
            }
        }
        let _ = writeln!(m, "n_averages = {}", t.n_averages);
        if let Some(tau) = t.exp_window_tau_s {
            let _ = writeln!(m, "exp_window_tau_s = {tau:?}");
        }
        for r in &t.responses {
            let _ = writeln!(
                m,
                "[[test.channel]]\ndof = {}\nnode = \"{}+X\"\nname = {}",
                r.channel.floor,
                r.channel.floor,
                q(&r.channel.name)
            );
        }
    }
    Ok(m)
}
