//! Integration tests of `tune`, one binary: the designs against an independent evaluation of the
//! loop, the discrete realisation, and the closed loop against Grunwald-Letnikov.

mod closed_loop;
mod design;
mod realise;
mod safety;
