pub mod fixture;
pub mod inspect;
pub mod simplify;
