//! The joint firmware under QEMU (mps2-an386), for the end-to-end tests that need it
//! (`firmware_e2e.rs`, `hil_e2e.rs`): `scripts/test-firmware.sh` builds the ELF and names it in
//! `SWG_FIRMWARE_ELF`.
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use swg_host::link::Link;
use swg_protocol::endpoint;

/// One QEMU running the joint firmware, its UART0 on a free local TCP port; killed on drop.
///
/// QEMU runs with `-icount shift=0`: virtual time is the instruction count (1 ns each), so the
/// firmware's SysTick tick and its timing counters (late ticks, overruns, missed periods)
/// measure the firmware alone. Without it SysTick follows the host's clock, and a loaded
/// machine (CI's two cores running the tests) would make ticks late that the firmware did not
/// delay. (The firmware never sleeps, so `-icount`'s `sleep` option does not matter.)
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
            .args(["-icount", "shift=0"])
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

    /// A link on which the firmware has answered. A freshly booted QEMU refuses connections
    /// while it opens its port and can reset the first connection (`Connection reset by peer`,
    /// seen in CI), so the device info is asked until it comes. A late answer to an earlier
    /// attempt, arriving on this link, carries another request's id and is discarded. A QEMU
    /// that has exited (its port taken, say) is reported with its status.
    pub fn ready_link(&mut self) -> Link {
        let address = self.address();
        let start = Instant::now();
        loop {
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("QEMU exited before the firmware answered on {address}: {status}");
            }
            let attempt = Link::open(&address, Duration::from_secs(2)).and_then(|mut link| {
                link.call::<endpoint::GetDeviceInfo>(&())?;
                Ok(link)
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
