pub mod bench;
pub mod build;
pub mod cut;
pub mod fixture;
pub mod inspect;
pub mod progress;
pub mod serve;
pub mod simplify;
