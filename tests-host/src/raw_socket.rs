//! A Linux AF_PACKET raw socket bound to one interface, carrying only EtherCAT frames
//! (EtherType 0x88A4). This is how `virtual-drive` meets real masters (SOEM, IgH,
//! TwinCAT, ethercrab) on the other end of a cable or a veth pair.

use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};

/// EtherType of EtherCAT frames.
pub const ETHERTYPE_ECAT: u16 = 0x88A4;

/// A raw socket on one interface.
pub struct RawSocket {
    fd: OwnedFd,
    ifindex: i32,
}

/// Why the socket could not be opened, in words a user can act on.
#[derive(Debug)]
pub enum OpenError {
    /// No interface of that name.
    NoSuchInterface(String),
    /// Raw sockets need root or CAP_NET_RAW.
    PermissionDenied(String),
    /// Anything else the kernel said.
    Other(io::Error),
}

impl std::fmt::Display for OpenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoSuchInterface(n) => write!(f, "network interface '{n}' does not exist (see `ip link`)"),
            Self::PermissionDenied(n) => write!(
                f,
                "no permission to open a raw socket on '{n}': run as root or give the binary CAP_NET_RAW \
                 (sudo setcap cap_net_raw+ep <binary>)"
            ),
            Self::Other(e) => write!(f, "raw socket: {e}"),
        }
    }
}

impl RawSocket {
    /// Opens a non-blocking raw socket for EtherCAT frames on `iface`.
    pub fn open(iface: &str) -> Result<Self, OpenError> {
        let name = CString::new(iface).map_err(|_| OpenError::NoSuchInterface(iface.into()))?;
        // SAFETY: plain libc calls with valid arguments; the fd is owned right away.
        let ifindex = unsafe { libc::if_nametoindex(name.as_ptr()) } as i32;
        if ifindex == 0 {
            return Err(OpenError::NoSuchInterface(iface.into()));
        }
        let proto = (ETHERTYPE_ECAT).to_be() as i32;
        // SAFETY: see above.
        let raw =
            unsafe { libc::socket(libc::AF_PACKET, libc::SOCK_RAW | libc::SOCK_NONBLOCK, proto) };
        if raw < 0 {
            let e = io::Error::last_os_error();
            return Err(match e.raw_os_error() {
                Some(libc::EPERM) | Some(libc::EACCES) => OpenError::PermissionDenied(iface.into()),
                _ => OpenError::Other(e),
            });
        }
        // SAFETY: `raw` is a fresh, valid descriptor we own.
        let fd = unsafe { OwnedFd::from_raw_fd(raw) };
        // SAFETY: zeroed sockaddr_ll is a valid starting value.
        let mut addr: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        addr.sll_family = libc::AF_PACKET as u16;
        addr.sll_protocol = ETHERTYPE_ECAT.to_be();
        addr.sll_ifindex = ifindex;
        // SAFETY: addr is a valid sockaddr_ll of the size passed.
        let rc = unsafe {
            libc::bind(
                fd.as_raw_fd(),
                &addr as *const libc::sockaddr_ll as *const libc::sockaddr,
                std::mem::size_of::<libc::sockaddr_ll>() as u32,
            )
        };
        if rc < 0 {
            return Err(OpenError::Other(io::Error::last_os_error()));
        }
        Ok(Self { fd, ifindex })
    }

    /// Receives one frame if one is waiting (non-blocking). Frames this socket sent
    /// itself are not returned (PACKET_OUTGOING is filtered).
    pub fn recv(&self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        loop {
            // SAFETY: zeroed sockaddr_ll is valid; recvfrom writes at most its size.
            let mut from: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
            let mut len = std::mem::size_of::<libc::sockaddr_ll>() as u32;
            // SAFETY: buf is valid for buf.len() bytes.
            let n = unsafe {
                libc::recvfrom(
                    self.fd.as_raw_fd(),
                    buf.as_mut_ptr().cast(),
                    buf.len(),
                    0,
                    &mut from as *mut libc::sockaddr_ll as *mut libc::sockaddr,
                    &mut len,
                )
            };
            if n < 0 {
                let e = io::Error::last_os_error();
                return match e.kind() {
                    io::ErrorKind::WouldBlock => Ok(None),
                    io::ErrorKind::Interrupted => continue,
                    _ => Err(e),
                };
            }
            if from.sll_pkttype == libc::PACKET_OUTGOING {
                continue;
            }
            return Ok(Some(n as usize));
        }
    }

    /// Sends one whole Ethernet frame.
    pub fn send(&self, frame: &[u8]) -> io::Result<()> {
        // SAFETY: zeroed sockaddr_ll is valid.
        let mut to: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        to.sll_family = libc::AF_PACKET as u16;
        to.sll_protocol = ETHERTYPE_ECAT.to_be();
        to.sll_ifindex = self.ifindex;
        to.sll_halen = 6;
        to.sll_addr[..6].copy_from_slice(frame.get(0..6).unwrap_or(&[0xFF; 6]));
        // SAFETY: frame and address are valid for the sizes passed.
        let n = unsafe {
            libc::sendto(
                self.fd.as_raw_fd(),
                frame.as_ptr().cast(),
                frame.len(),
                0,
                &to as *const libc::sockaddr_ll as *const libc::sockaddr,
                std::mem::size_of::<libc::sockaddr_ll>() as u32,
            )
        };
        if n < 0 {
            Err(io::Error::last_os_error())
        } else {
            Ok(())
        }
    }

    /// Waits up to `timeout_us` for a frame to become readable.
    pub fn wait_readable(&self, timeout_us: u64) -> io::Result<bool> {
        let mut pfd = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = timeout_us.div_ceil(1000).min(i32::MAX as u64) as i32;
        // SAFETY: one valid pollfd.
        let rc = unsafe { libc::poll(&mut pfd, 1, ms) };
        if rc < 0 {
            let e = io::Error::last_os_error();
            if e.kind() == io::ErrorKind::Interrupted {
                return Ok(false);
            }
            return Err(e);
        }
        Ok(rc > 0)
    }
}
