pub mod bench;
pub mod cut;
pub mod fixture;
pub mod inspect;
pub mod serve;
pub mod build;
pub mod progress;
pub mod simplify;
