//! FRF-based model updating, paper Sections 3.1-3.2 (Eqs. 17-24): bounded multistart
//! least squares on FRF magnitudes, with analytical Jacobians, plus the FDAC and RSD
//! metrics of Section 4.

pub mod lsq;
