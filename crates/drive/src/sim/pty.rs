//! The pseudo-terminal the host opens: the pair, the non-blocking master, the unread count, the
//! link that follows a reconnect.

use crate::error::{Error, Result};
use serialport::{SerialPort, TTYPort};
use std::os::fd::AsRawFd;
use std::time::Duration;

/// Open a pty pair; keep the master, close the slave (the host opens it by name).
pub(super) fn open_pty() -> Result<(TTYPort, String)> {
    let (mut master, slave) = TTYPort::pair().map_err(|e| Error::Port {
        path: "pty".into(),
        source: e,
    })?;
    let name = slave
        .name()
        .ok_or_else(|| Error::Protocol("pty slave has no name".into()))?;
    drop(slave);
    let _ = master.set_timeout(Duration::ZERO);
    Ok((master, name))
}

/// Virtual time: the master in non-blocking mode (what the pty cannot take waits in the
/// simulator), and the slave held open to see how much the host has not read yet.
pub(super) fn watch_pty(master: &TTYPort, slave_name: &str) -> Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    let fd = master.as_raw_fd();
    // SAFETY: fcntl on a descriptor we own, no pointers.
    let ok = unsafe {
        let fl = libc::fcntl(fd, libc::F_GETFL);
        fl >= 0 && libc::fcntl(fd, libc::F_SETFL, fl | libc::O_NONBLOCK) == 0
    };
    if !ok {
        return Err(Error::Io(std::io::Error::last_os_error()));
    }
    let slave = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
        .open(slave_name)?;
    Ok(slave)
}

/// Bytes waiting to be read on the pty slave (FIONREAD); 0 if that cannot be known.
pub(super) fn unread(slave: &std::fs::File) -> usize {
    let mut n: libc::c_int = 0;
    // SAFETY: FIONREAD writes one c_int through a valid pointer.
    let r = unsafe { libc::ioctl(slave.as_raw_fd(), libc::FIONREAD, &mut n) };
    if r == 0 {
        n.max(0) as usize
    } else {
        0
    }
}

pub(super) fn retarget_link(link: &std::path::Path, target: &str) -> Result<()> {
    let tmp = link.with_extension("tmp-link");
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(target, &tmp)?;
    std::fs::rename(&tmp, link)?;
    Ok(())
}
