//! A simulated F2812 drive speaking the protocol on a pseudo-terminal.
//!
//! [`DriveSim::spawn`] opens a pty pair (`serialport::TTYPort::pair()`), keeps the master side and
//! runs the "firmware" in a thread; a host opens [`DriveSim::port_path`] (the slave side, or a
//! stable symlink to it when [`SimConfig::link`] is set) like any serial port. The simulator
//! models:
//!
//! - the motor: a fractional PMSM model simulated by [`fracsim::Simulator`] (default: the paper's
//!   time-domain model `6.82 / (2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)`), with hidden effects
//!   ([`Effects`]): Coulomb friction, input delay, torque ripple, measurement noise, speed
//!   quantisation;
//! - the line: baud-rate pacing in both directions (a pty paces nothing), a 16-byte receive FIFO
//!   that overflows while the firmware's communication task is stalled, a transmit buffer of a few
//!   DATA blocks (whole blocks dropped and counted when full);
//! - faults ([`Faults`]): bit flips, dropped bytes, bursts, whole-frame corruption, a stall, a
//!   disconnect and reconnect (with a link, the link is removed while the pty is closed, as an
//!   unplugged adapter's device node is), a drive reset; and one lost answer ([`DriveSim::lose_next_answer`]).
//!
//! Its clock ([`SimClock`]) is the wall clock by default: samples are produced in batches every
//! ~0.5 ms as their time comes, as a real drive would. In virtual time ([`SimClock::Virtual`]) the
//! same drive runs as fast as the host allows, waiting for the host only where the protocol needs
//! it (the host reading what was sent, the keepalive; a host in the same process keeps its
//! keepalive on the drive's clock, [`crate::vclock`]).

mod config;
mod effects;
mod faults;
mod firmware;
mod handle;
mod plant;
mod pty;
mod stats;

pub use config::{
    FirmwareKind, SimClock, SimConfig, VIRTUAL_HOST_GRACE, VIRTUAL_MAX_UNREAD, VIRTUAL_STEP,
};
pub use effects::{Effects, MAX_DELAY_S};
pub use faults::{FaultAt, Faults, MAX_FAULT_DURATION};
pub use handle::DriveSim;
pub use stats::SimStats;
