pub mod accuracy;
pub mod bench;
pub mod info;
pub mod run;
