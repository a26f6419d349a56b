//! hooke in a web page: the GPU solver and the renderer on the browser's WebGPU, the state
//! resident on the GPU and drawn from it, as in `hooke view`.
//!
//! The page's JavaScript (`web/main.js`) owns the canvas, the controls and the animation loop;
//! it calls [`Page`] once per frame and forwards pointer input. Everything the page does
//! to the cloth goes through the engine's [`hooke::live::LiveSimulation`] and
//! [`hooke::pointer::Pointer`], the same as the viewer's window.
//!
//! Build with `./run web` (wasm32-unknown-unknown, then `wasm-bindgen --target web`).

mod page;
pub mod scenes;

pub use page::Page;
