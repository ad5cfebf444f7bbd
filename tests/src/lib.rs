//! Shared helpers of Antumbra's cross-validation tests: loading the committed
//! third-party data, generating scenes and rays, and running the Embree oracle
//! (`tests/oracle/embree_oracle.py`, see its README for the file formats).

pub mod data;
pub mod oracle;
pub mod scenes;
pub mod ssv;
