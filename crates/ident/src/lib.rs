//! # ident: fractional-order system identification
