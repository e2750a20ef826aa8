//! # drive: the F2812 serial protocol, client and simulator
