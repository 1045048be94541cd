//! Landscape evolution: stream-power incision with uplift ([`stream_power`], Braun and Willett
//! 2013) and linear hillslope diffusion ([`diffusion`], the ADI scheme of fastscapelib).

pub mod diffusion;
pub mod fans;
pub mod hydraulic;
pub mod job;
pub mod stream_power;
pub mod thermal;

#[cfg(test)]
mod tests;

pub use diffusion::{DiffusionScratch, diffuse};
pub use stream_power::{
    RunFigures, StepFigures, StreamPowerParams, StreamPowerScratch, Uplift, base_level_mask, run,
    step,
};
