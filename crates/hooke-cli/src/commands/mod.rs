pub mod accuracy;
pub mod bench;
pub mod info;
pub mod render;
pub mod run;
pub mod selfcollision_study;
