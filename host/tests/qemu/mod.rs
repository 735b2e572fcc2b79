//! The joint firmware under QEMU (mps2-an386), for the end-to-end tests that need it
//! (`firmware_e2e.rs`, `hil_e2e.rs`): `scripts/test-firmware.sh` builds the ELF and names it in
//! `SWG_FIRMWARE_ELF`.
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use swg_host::link::Link;

/// One QEMU running the joint firmware, its UART0 on a free local TCP port; killed on drop.
pub struct Qemu {
    child: Child,
    port: u16,
}

impl Qemu {
    pub fn boot() -> Qemu {
        let elf = std::env::var_os("SWG_FIRMWARE_ELF")
            .map(PathBuf::from)
            .expect("SWG_FIRMWARE_ELF must name the joint-qemu ELF (see scripts/test-firmware.sh)");
        // A port that was free a moment ago; tests running in parallel each get their own.
        let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let child = Command::new("qemu-system-arm")
            .args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-display", "none", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-serial")
            .arg(format!("tcp:127.0.0.1:{port},server=on,wait=off,nodelay=on"))
            .arg("-kernel")
            .arg(&elf)
            // defmt frames (binary) on stdout: not needed here.
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("qemu-system-arm starts");
        Qemu { child, port }
    }

    pub fn address(&self) -> String {
        format!("tcp://127.0.0.1:{}", self.port)
    }

    /// A link on which the firmware has answered, with nothing stale in flight. A freshly
    /// booted QEMU refuses connections while it opens its port, can reset the first connection
    /// (`Connection reset by peer`, seen in CI), or answers a request late, on the next
    /// connection. So the device info is asked until it comes; then that link is dropped after
    /// a pause in which any late answer arrives (and is lost with it), and a new one is opened
    /// and checked: its first response is to its own request. A QEMU that has exited (its port
    /// taken, say) is reported with its status.
    pub fn ready_link(&mut self) -> Link {
        let address = self.address();
        let answers = |timeout| {
            Link::open(&address, timeout).and_then(|mut link| {
                link.device_info()?;
                Ok(link)
            })
        };
        let start = Instant::now();
        loop {
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("QEMU exited before the firmware answered on {address}: {status}");
            }
            let attempt = answers(Duration::from_millis(500)).and_then(|first| {
                std::thread::sleep(Duration::from_millis(300));
                drop(first);
                answers(Duration::from_secs(2))
            });
            match attempt {
                Ok(link) => return link,
                Err(_) if start.elapsed() < Duration::from_secs(20) => std::thread::sleep(Duration::from_millis(100)),
                Err(error) => panic!("the firmware does not answer on {address}: {error}"),
            }
        }
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
