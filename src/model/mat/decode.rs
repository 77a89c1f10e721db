//! Byte-level decoding of MATLAB v5 `.mat` files: the 128-byte header, top-level
//! `miMATRIX` elements (plain or zlib-compressed `miCOMPRESSED`), and the numeric data of
//! every class MATLAB stores numbers in (double, single, int8..int64, uint8..uint64,
//! logical, sparse), converted to `f64`.
//!
//! The `matfile` crate (0.5) refuses a whole file when one of its variables is `int32`
//! (it checks the data of an `mxINT32_CLASS` array against `miUINT32`), and the bridge
//! model stores some influence matrices as integers; hence this reader. Element layout:
//! MathWorks, "MAT-File Format", version 5, sections 1-3.

use std::io::Read;

/// One top-level variable as the element tags describe it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VariableInfo {
    pub name: String,
    /// MATLAB class, e.g. "double", "int32", "sparse", "struct".
    pub class: &'static str,
    pub dims: Vec<usize>,
}

/// The numbers of a numeric variable, converted to `f64`, column-major.
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    Dense {
        re: Vec<f64>,
        im: Option<Vec<f64>>,
    },
    /// MATLAB's compressed-column storage: row indices `ir` of the entries of column `c`
    /// at `jc[c]..jc[c + 1]`.
    Sparse {
        ir: Vec<usize>,
        jc: Vec<usize>,
        re: Vec<f64>,
        im: Option<Vec<f64>>,
    },
}

/// A decoded top-level variable; `values` is `None` for non-numeric classes (cell,
/// struct, char, object).
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    pub info: VariableInfo,
    pub values: Option<Values>,
}

pub(super) const MI_INT8: u32 = 1;
pub(super) const MI_INT32: u32 = 5;
pub(super) const MI_UINT32: u32 = 6;
pub(super) const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const CLASS_SPARSE: u32 = 5;
const FLAG_COMPLEX: u32 = 0x0800;

pub(super) fn class_name(c: u32) -> &'static str {
    match c {
        1 => "cell",
        2 => "struct",
        3 => "object",
        4 => "char",
        5 => "sparse",
        6 => "double",
        7 => "single",
        8 => "int8",
        9 => "uint8",
        10 => "int16",
        11 => "uint16",
        12 => "int32",
        13 => "uint32",
        14 => "int64",
        15 => "uint64",
        _ => "unknown",
    }
}

/// Every top-level variable of a MAT v5 file, numeric ones with their values. Errors
/// say what is wrong with the bytes and, once its name is known, name the variable.
pub fn decode(bytes: &[u8]) -> std::result::Result<Vec<Variable>, String> {
    walk(bytes, true)
}

/// The top-level variables (name, class, dimensions) from the element tags alone.
pub fn scan(bytes: &[u8]) -> std::result::Result<Vec<VariableInfo>, String> {
    Ok(walk(bytes, false)?.into_iter().map(|v| v.info).collect())
}

fn walk(bytes: &[u8], with_values: bool) -> std::result::Result<Vec<Variable>, String> {
    if bytes.len() < 128 {
        return Err(format!(
            "{} bytes, shorter than the 128-byte MAT v5 header",
            bytes.len()
        ));
    }
    let big = match &bytes[126..128] {
        b"IM" => false,
        b"MI" => true,
        other => {
            return Err(format!(
                "bad endian indicator {:?} at byte 126 (expected \"IM\" or \"MI\"; MAT v7.3 \
                 HDF5 files are not supported)",
                String::from_utf8_lossy(other)
            ))
        }
    };
    let rd = Reader { big };
    let mut out = Vec::new();
    let mut pos = 128;
    while pos + 8 <= bytes.len() {
        let (ty, n, data_at) = rd.tag(bytes, pos)?;
        let end = data_at
            .checked_add(n)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| format!("element at byte {pos} runs past the end of the file"))?;
        let body = &bytes[data_at..end];
        match ty {
            MI_MATRIX => out.push(rd.matrix(body, with_values)?),
            MI_COMPRESSED => {
                let mut inner = Vec::new();
                flate2::read::ZlibDecoder::new(body)
                    .read_to_end(&mut inner)
                    .map_err(|e| format!("compressed element at byte {pos}: {e}"))?;
                let (ity, inn, iat) = rd.tag(&inner, 0)?;
                if ity == MI_MATRIX {
                    let iend = iat
                        .checked_add(inn)
                        .filter(|&e| e <= inner.len())
                        .ok_or_else(|| {
                            format!("compressed element at byte {pos} is shorter than its tag says")
                        })?;
                    out.push(rd.matrix(&inner[iat..iend], with_values)?);
                }
            }
            _ => {}
        }
        // Compressed elements are not padded; others end on an 8-byte boundary.
        pos = if ty == MI_COMPRESSED {
            end
        } else {
            end.div_ceil(8) * 8
        };
    }
    Ok(out)
}

struct Reader {
    big: bool,
}

impl Reader {
    fn bytes<const N: usize>(&self, b: &[u8], at: usize) -> std::result::Result<[u8; N], String> {
        let mut s: [u8; N] = b
            .get(at..at + N)
            .and_then(|s| s.try_into().ok())
            .ok_or_else(|| format!("truncated element at byte {at}"))?;
        if self.big {
            s.reverse();
        }
        Ok(s)
    }

    fn u32_at(&self, b: &[u8], at: usize) -> std::result::Result<u32, String> {
        Ok(u32::from_le_bytes(self.bytes(b, at)?))
    }

    /// (type, byte count, offset of the data) of the element tag at `at`; handles the
    /// small-element format (count in the upper 16 bits of the first word).
    fn tag(&self, b: &[u8], at: usize) -> std::result::Result<(u32, usize, usize), String> {
        let w = self.u32_at(b, at)?;
        if w >> 16 != 0 {
            Ok((w & 0xFFFF, (w >> 16) as usize, at + 4))
        } else {
            Ok((w, self.u32_at(b, at + 4)? as usize, at + 8))
        }
    }

    /// The sub-element at `*pos` (type and its bytes); advances `*pos` past its padding.
    fn element<'a>(
        &self,
        b: &'a [u8],
        pos: &mut usize,
    ) -> std::result::Result<(u32, &'a [u8]), String> {
        let (ty, n, at) = self.tag(b, *pos)?;
        let data = b
            .get(at..at + n)
            .ok_or_else(|| format!("sub-element at byte {} runs past its matrix", *pos))?;
        *pos = (at + n).div_ceil(8) * 8;
        Ok((ty, data))
    }

    /// An `miMATRIX`: array flags, dimensions, name and, when `with_values` and the class
    /// is numeric, the data.
    fn matrix(&self, b: &[u8], with_values: bool) -> std::result::Result<Variable, String> {
        let mut pos = 0;
        let (ty, flags) = self.element(b, &mut pos)?;
        if ty != MI_UINT32 || flags.len() != 8 {
            return Err("matrix without its array-flags sub-element".into());
        }
        let flags = self.u32_at(flags, 0)?;
        let class = flags & 0xFF;
        let (ty, dims) = self.element(b, &mut pos)?;
        if ty != MI_INT32 {
            return Err("matrix without its dimensions sub-element".into());
        }
        let dims = (0..dims.len() / 4)
            .map(|i| {
                let d = i32::from_le_bytes(self.bytes(dims, 4 * i)?);
                usize::try_from(d).map_err(|_| format!("negative dimension {d}"))
            })
            .collect::<std::result::Result<Vec<_>, _>>()?;
        let (ty, name) = self.element(b, &mut pos)?;
        if ty != MI_INT8 {
            return Err("matrix without its name sub-element".into());
        }
        let info = VariableInfo {
            name: String::from_utf8_lossy(name).into_owned(),
            class: class_name(class),
            dims,
        };
        let numeric = matches!(class, 6..=15);
        let values = if !with_values || !(numeric || class == CLASS_SPARSE) {
            None
        } else {
            let complex = flags & FLAG_COMPLEX != 0;
            let v = if class == CLASS_SPARSE {
                self.sparse(b, &mut pos, &info, complex)
            } else {
                self.dense(b, &mut pos, &info, complex)
            };
            Some(v.map_err(|e| format!("variable `{}`: {e}", info.name))?)
        };
        Ok(Variable { info, values })
    }

    fn dense(
        &self,
        b: &[u8],
        pos: &mut usize,
        info: &VariableInfo,
        complex: bool,
    ) -> std::result::Result<Values, String> {
        let len: usize = info.dims.iter().product();
        let re = self.numbers(b, pos, len, "real part")?;
        let im = if complex {
            Some(self.numbers(b, pos, len, "imaginary part")?)
        } else {
            None
        };
        Ok(Values::Dense { re, im })
    }

    fn sparse(
        &self,
        b: &[u8],
        pos: &mut usize,
        info: &VariableInfo,
        complex: bool,
    ) -> std::result::Result<Values, String> {
        let [rows, cols] = info.dims[..] else {
            return Err(format!("sparse array with dimensions {:?}", info.dims));
        };
        let (ty, ir) = self.element(b, pos)?;
        let ir = self.convert(ty, ir, "row indices")?;
        let (ty, jc) = self.element(b, pos)?;
        let jc = self.convert(ty, jc, "column starts")?;
        let index = |x: f64| x as usize;
        let jc: Vec<usize> = jc.iter().map(|&x| index(x)).collect();
        if jc.len() != cols + 1 || jc.windows(2).any(|w| w[0] > w[1]) {
            return Err(format!(
                "sparse column starts are not {} non-decreasing values",
                cols + 1
            ));
        }
        let nnz = jc[cols];
        if ir.len() < nnz || ir[..nnz].iter().any(|&r| r < 0.0 || r >= rows as f64) {
            return Err(format!("sparse row indices outside 0..{rows}"));
        }
        let ir: Vec<usize> = ir[..nnz].iter().map(|&x| index(x)).collect();
        let mut re = self.numbers(b, pos, usize::MAX, "real part")?;
        let mut im = if complex {
            Some(self.numbers(b, pos, usize::MAX, "imaginary part")?)
        } else {
            None
        };
        for v in std::iter::once(&mut re).chain(im.as_mut()) {
            // MATLAB pads the value arrays of an all-zero sparse matrix to one entry.
            if v.len() < nnz {
                return Err(format!("{} sparse values for {nnz} entries", v.len()));
            }
            v.truncate(nnz);
        }
        Ok(Values::Sparse { ir, jc, re, im })
    }

    /// The numeric sub-element at `*pos`, of exactly `len` values unless `len` is
    /// `usize::MAX`.
    fn numbers(
        &self,
        b: &[u8],
        pos: &mut usize,
        len: usize,
        what: &str,
    ) -> std::result::Result<Vec<f64>, String> {
        if *pos >= b.len() && len == 0 {
            return Ok(Vec::new());
        }
        let (ty, data) = self.element(b, pos)?;
        let v = self.convert(ty, data, what)?;
        if len != usize::MAX && v.len() != len {
            return Err(format!("{what} has {} values for {len} elements", v.len()));
        }
        Ok(v)
    }

    /// Converts the bytes of one numeric data element of MAT type `ty` to `f64`.
    #[allow(clippy::modulo_one)] // the macro checks whole values for every width, 1 included
    fn convert(&self, ty: u32, d: &[u8], what: &str) -> std::result::Result<Vec<f64>, String> {
        macro_rules! conv {
            ($t:ty) => {{
                const N: usize = std::mem::size_of::<$t>();
                if d.len() % N != 0 {
                    return Err(format!(
                        "{what}: {} bytes is not a whole number of {}-byte values",
                        d.len(),
                        N
                    ));
                }
                (0..d.len() / N)
                    .map(|i| Ok(<$t>::from_le_bytes(self.bytes::<N>(d, i * N)?) as f64))
                    .collect()
            }};
        }
        match ty {
            1 => conv!(i8),
            2 => conv!(u8),
            3 => conv!(i16),
            4 => conv!(u16),
            5 => conv!(i32),
            6 => conv!(u32),
            7 => conv!(f32),
            9 => conv!(f64),
            12 => conv!(i64),
            13 => conv!(u64),
            _ => Err(format!(
                "{what} has MAT data type {ty}, which is not numeric"
            )),
        }
    }
}
