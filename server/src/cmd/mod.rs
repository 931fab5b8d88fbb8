pub mod fixture;
pub mod inspect;
