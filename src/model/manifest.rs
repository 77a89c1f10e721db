//! General models from files: a TOML manifest naming the matrices of
//! `K(alpha) = K0 + sum_r alpha_r K0_r` and `M(beta) = M0 + sum_r beta_r M0_r` (paper
//! Eqs. 20-21), read either from Matrix Market files or from variables of one MATLAB
//! `.mat` file, so that a model exported from any FE package can be updated.
//!
//! ```toml
//! # Matrix Market source: each matrix is a file, relative to the manifest.
//! k0 = "K0.mtx"
//! m0 = "M0.mtx"
//! ground_influence = [1.0, 1.0, 1.0]   # optional; ones by default
//! measured_dofs = [1, 3]               # optional; 1-based DOF numbers of the sensors
//! [[alpha]]
//! name = "k1"
//! unit = "N/m"                          # optional
//! matrix = "K1.mtx"
//! [[beta]]
//! name = "m1"
//! matrix = "M1.mtx"
//! ```
//!
//! ```toml
//! # .mat source: the same keys name variables of the file.
//! mat = "{shared}/data/real/bridge-fe/SteelPedestrianBridgeExp.mat"
//! k0 = ["K_Frame", "K_Truss"]           # a list is the sum of its matrices
//! m0 = "M0"
//! measured_dofs = "measDOFs"            # a variable holding 1-based DOF numbers
//! [[alpha]]
//! name = "Frame"
//! matrix = "K_Frame"
//! ```
//!
//! Every matrix entry (`k0`, `m0`, `matrix`) is one name or a list whose matrices are
//! summed; `k0 = []` is the zero matrix. `ground_influence` is a list of numbers or, with
//! a `.mat` source, a variable name. Paths are relative to the manifest; a path that
//! starts with `{shared}` is relative to the shared data folder instead:
//! `$FRFBAYES_SHARED_DIR` when set, else `../shared` from the current directory (the
//! repository root, when `frfbayes` and `cargo test` run there).

use super::mat::MatData;
use super::mtx::read_matrix_market_triplets;
use super::sparse::Triplets;
use super::{Parameter, StructuralModel};
use crate::error::{Error, Result};
use nalgebra::DVector;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The TOML manifest of a general model (see the module docs for the format).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelManifest {
    /// A MATLAB `.mat` file whose variables the matrix entries name; without it, the
    /// entries are Matrix Market files.
    #[serde(default)]
    pub mat: Option<String>,
    pub k0: MatrixSpec,
    pub m0: MatrixSpec,
    #[serde(default)]
    pub ground_influence: Option<VectorSpec>,
    #[serde(default)]
    pub measured_dofs: Option<VectorSpec>,
    #[serde(default)]
    pub alpha: Vec<InfluenceEntry>,
    #[serde(default)]
    pub beta: Vec<InfluenceEntry>,
}

/// A matrix: one file or variable, or the sum of several.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum MatrixSpec {
    One(String),
    Sum(Vec<String>),
}

impl MatrixSpec {
    fn names(&self) -> Vec<&str> {
        match self {
            MatrixSpec::One(s) => vec![s.as_str()],
            MatrixSpec::Sum(v) => v.iter().map(String::as_str).collect(),
        }
    }
}

/// A vector: its values, or the name of a `.mat` variable holding them.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum VectorSpec {
    Values(Vec<f64>),
    Variable(String),
}

/// One influence matrix of the manifest.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InfluenceEntry {
    pub name: String,
    #[serde(default)]
    pub unit: Option<String>,
    pub matrix: MatrixSpec,
}

/// The shared data folder: `$FRFBAYES_SHARED_DIR` when set, else `../shared`.
pub fn shared_root() -> PathBuf {
    std::env::var_os("FRFBAYES_SHARED_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared"))
}

/// `path` with a leading `{shared}` replaced by [`shared_root`], else relative to `dir`.
fn resolve(dir: &Path, path: &str) -> PathBuf {
    match path.strip_prefix("{shared}") {
        Some(rest) => shared_root().join(rest.trim_start_matches(['/', '\\'])),
        None => dir.join(path),
    }
}

/// Where the matrices come from.
enum Source {
    Files(PathBuf),
    Mat(MatData),
}

impl Source {
    /// A named matrix and a label for messages (the file, or the variable and file).
    fn matrix(&self, name: &str) -> Result<(String, Triplets)> {
        match self {
            Source::Files(dir) => {
                let p = resolve(dir, name);
                Ok((p.display().to_string(), read_matrix_market_triplets(&p)?))
            }
            Source::Mat(mat) => Ok((
                format!("`{name}` in {}", mat.path().display()),
                mat.real_triplets(name)?,
            )),
        }
    }

    fn vector(&self, spec: &VectorSpec, key: &str) -> Result<(String, Vec<f64>)> {
        match (spec, self) {
            (VectorSpec::Values(v), _) => Ok((format!("`{key}`"), v.clone())),
            (VectorSpec::Variable(name), Source::Mat(mat)) => Ok((
                format!("`{key}` (`{name}` in {})", mat.path().display()),
                mat.vector(name, None)?,
            )),
            (VectorSpec::Variable(name), Source::Files(_)) => Err(Error::Usage(format!(
                "`{key} = \"{name}\"` names a variable, which needs `mat = ...`; give the \
                 values as a list"
            ))),
        }
    }

    /// The sum of the matrices `spec` names, each checked (square, `n x n` when `n` is
    /// known, symmetric, finite).
    fn sum(&self, spec: &MatrixSpec, key: &str, n: Option<usize>) -> Result<Option<Triplets>> {
        let mut total: Option<Triplets> = None;
        for name in spec.names() {
            let (label, t) = self.matrix(name)?;
            let want = n.or(total.as_ref().map(|t| t.rows));
            super::validate::check_matrix(&format!("{key}: {label}"), &t, want)?;
            match &mut total {
                None => total = Some(t),
                Some(s) => s.entries.extend(t.entries),
            }
        }
        Ok(total)
    }
}

impl ModelManifest {
    /// Reads a manifest and every matrix it names, and validates the model. Errors name
    /// the manifest and, where one is at fault, the matrix file or variable.
    pub fn load(path: &Path) -> Result<StructuralModel> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::load_text(&text, path, path.parent().unwrap_or(Path::new(".")))
    }

    /// A manifest given as text: `label` names it in messages and relative paths are
    /// relative to `dir` (a study's built-in manifest, its `{shared}` already replaced).
    pub fn load_text(text: &str, label: &Path, dir: &Path) -> Result<StructuralModel> {
        let path = label;
        let manifest: ModelManifest =
            toml::from_str(text).map_err(|e| Error::invalid(path, e.to_string()))?;
        manifest.build(dir).map_err(|e| match e {
            Error::Model(what) | Error::Usage(what) => Error::invalid(path, what),
            other => other,
        })
    }

    /// The model, with paths relative to `dir`.
    fn build(&self, dir: &Path) -> Result<StructuralModel> {
        let source = match &self.mat {
            Some(p) => Source::Mat(MatData::open(&resolve(dir, p))?),
            None => Source::Files(dir.to_path_buf()),
        };
        let m0 = source
            .sum(&self.m0, "m0", None)?
            .ok_or_else(|| Error::Usage("`m0` names no matrix".into()))?;
        let n = m0.rows;
        let k0 = source.sum(&self.k0, "k0", Some(n))?.unwrap_or(Triplets {
            rows: n,
            cols: n,
            entries: Vec::new(),
        });
        let influence =
            |list: &[InfluenceEntry], key: &str| -> Result<Vec<(Parameter, Triplets)>> {
                list.iter()
                    .map(|e| {
                        let what = format!("{key} `{}`", e.name);
                        let t = source
                            .sum(&e.matrix, &what, Some(n))?
                            .ok_or_else(|| Error::Usage(format!("{what} names no matrix")))?;
                        let p = Parameter {
                            name: e.name.clone(),
                            unit: e.unit.clone().unwrap_or_else(|| "-".into()),
                            nominal: None,
                        };
                        Ok((p, t))
                    })
                    .collect()
            };
        let ka = influence(&self.alpha, "alpha")?;
        let mb = influence(&self.beta, "beta")?;
        let ground = match &self.ground_influence {
            None => None,
            Some(spec) => {
                let (label, v) = source.vector(spec, "ground_influence")?;
                super::validate::check_vector(&label, &v, n)?;
                Some(DVector::from_vec(v))
            }
        };
        let measured = match &self.measured_dofs {
            None => Vec::new(),
            Some(spec) => {
                let (label, v) = source.vector(spec, "measured_dofs")?;
                super::validate::dof_list(&label, &v, n)?
            }
        };
        let dense =
            |v: Vec<(Parameter, Triplets)>| v.into_iter().map(|(p, t)| (p, t.to_dense())).collect();
        let model = StructuralModel::from_matrices(
            k0.to_dense(),
            m0.to_dense(),
            dense(ka),
            dense(mb),
            ground,
        )?;
        model.with_measured_dofs(measured)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn manifest_model_equals_shear_frame() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        write(
            d,
            "K0.mtx",
            "%%MatrixMarket matrix coordinate real symmetric\n2 2 3\n1 1 30\n2 1 -20\n2 2 20\n",
        );
        write(
            d,
            "M0.mtx",
            "%%MatrixMarket matrix array real general\n% comment\n2 2\n1\n0\n0\n2\n",
        );
        write(
            d,
            "K1.mtx",
            "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 10\n",
        );
        write(
            d,
            "K2.mtx",
            "%%MatrixMarket matrix coordinate real symmetric\n2 2 3\n1 1 20\n2 1 -20\n2 2 20\n",
        );
        let man = write(
            d,
            "model.toml",
            "k0 = \"K0.mtx\"\nm0 = \"M0.mtx\"\n[[alpha]]\nname = \"k1\"\nmatrix = \"K1.mtx\"\n[[alpha]]\nname = \"k2\"\nmatrix = \"K2.mtx\"\n",
        );
        let model = ModelManifest::load(&man).unwrap();
        let sf = StructuralModel::shear_frame(&[1.0, 2.0], &[10.0, 20.0]).unwrap();
        let a = [0.3, -0.2];
        assert!((model.stiffness(&a) - sf.stiffness(&a)).amax() < 1e-12);
        assert!((model.mass(&[]) - sf.mass(&[0.0, 0.0])).amax() < 1e-12);
    }
}
