//! The device training runs on: Burn's CPU backend, or, with the `gpu` feature, a wgpu adapter
//! through Burn's CubeCL backend. A software rasterizer (Mesa's lavapipe) is taken only when
//! asked for, since it trains slower than the CPU backend; tests ask for it to run the GPU code
//! paths without a GPU.

use anyhow::Result;
use burn::tensor::Device;

/// Where `pwenc` trains (`--device`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum DeviceChoice {
    /// A GPU when the build has GPU support and a wgpu adapter that is not a software
    /// rasterizer exists, else the CPU.
    #[default]
    Auto,
    Cpu,
    /// A GPU, or an error saying why there is none. `PWGS_ALLOW_SOFTWARE_GPU=1` accepts a
    /// software rasterizer (Mesa's lavapipe), for tests.
    Gpu,
}

impl DeviceChoice {
    /// The device this choice names on this machine; `Auto` says why it fell back to the CPU
    /// in `fell_back`.
    pub fn resolve(self, fell_back: impl FnOnce(&anyhow::Error)) -> Result<TrainingDevice> {
        let allow_software = std::env::var_os("PWGS_ALLOW_SOFTWARE_GPU").is_some_and(|v| v == "1");
        match self {
            Self::Cpu => Ok(TrainingDevice::cpu()),
            Self::Gpu => TrainingDevice::gpu(allow_software),
            Self::Auto => Ok(TrainingDevice::gpu(allow_software).unwrap_or_else(|e| {
                fell_back(&e);
                TrainingDevice::cpu()
            })),
        }
    }
}

/// A device and what it is, for logs and reports.
#[derive(Debug, Clone)]
pub struct TrainingDevice {
    pub device: Device,
    /// The adapter's name, its API and driver, or the CPU backend's name.
    pub name: String,
    pub gpu: bool,
}

impl TrainingDevice {
    /// Burn's CPU backend.
    pub fn cpu() -> Self {
        Self { device: Device::flex(), name: "CPU (Burn flex backend)".to_string(), gpu: false }
    }

    /// The wgpu adapter wgpu ranks first for high performance; a software rasterizer only with
    /// `allow_software`. Fails, without panicking, when there is none. The adapter is opened
    /// once per process (Burn registers its runtime once); later calls return it again.
    #[cfg(feature = "gpu")]
    pub fn gpu(allow_software: bool) -> Result<Self> {
        use burn::tensor::DeviceKind;
        use burn::tensor::wgpu::wgpu::DeviceType;
        use std::sync::OnceLock;
        static OPENED: OnceLock<std::result::Result<(Device, String, bool), String>> = OnceLock::new();
        let opened = OPENED.get_or_init(|| {
            minimal_autotune();
            let (device, setup) = Device::wgpu_options()
                .device_kind(DeviceKind::DefaultDevice)
                .init_with_setup()
                .map_err(|e| format!("no wgpu adapter could be opened: {e}"))?;
            let info = setup.adapter.get_info();
            let name = format!("{} ({:?}, {} {})", info.name, info.backend, info.driver, info.driver_info);
            Ok((device, name, info.device_type == DeviceType::Cpu))
        });
        let (device, name, software) = opened.as_ref().map_err(|e| anyhow::anyhow!("{e}"))?;
        anyhow::ensure!(allow_software || !software, "the only wgpu adapter is a software rasterizer: {name}");
        Ok(Self { device: device.clone(), name: name.clone(), gpu: true })
    }

    /// Without the `gpu` feature there is no GPU backend to open.
    #[cfg(not(feature = "gpu"))]
    pub fn gpu(_allow_software: bool) -> Result<Self> {
        anyhow::bail!("this build has no GPU backend (build with the `gpu` feature)")
    }

    /// Bytes the device's memory pools hold for tensors now, where the backend says it.
    pub fn bytes_in_use(&self) -> Option<u64> {
        self.device.memory_pool_usage().map(|u| u.bytes_in_use)
    }

    /// Bytes the device's memory pools have reserved now, where the backend says it: what the
    /// run takes from the device, its peak when read after the largest step.
    pub fn bytes_reserved(&self) -> Option<u64> {
        self.device.memory_pool_usage().map(|u| u.bytes_reserved)
    }

    /// Waits for the device's queued work, so that a timing covers it.
    pub fn sync(&self) -> Result<()> {
        self.device.sync().map_err(|e| anyhow::anyhow!("the device failed: {e:?}"))
    }
}

/// Per-step timing for finding where a device's steps go (`PWGS_TRACE_STEPS` set): each step's
/// wall time as `[STEP] k ms` on stderr, where, with `CUBECL_DEBUG_LOG=stderr`, CubeCL's lines
/// for the kernels it compiled during that step come before it
/// (`scripts/profile_kernels.sh --trace` counts them). A step that reads a value back from the
/// device (every training step does: its loss) has finished its device work when it returns.
pub struct StepTrace {
    last: Option<std::time::Instant>,
}

impl StepTrace {
    /// Tracing when `PWGS_TRACE_STEPS` is set, from now.
    pub fn from_env() -> Self {
        Self { last: std::env::var_os("PWGS_TRACE_STEPS").map(|_| std::time::Instant::now()) }
    }

    /// Step `k` has returned.
    pub fn step(&mut self, k: u32) {
        if let Some(last) = self.last.as_mut() {
            eprintln!("[STEP] {k} {:.1} ms", last.elapsed().as_secs_f64() * 1e3);
            *last = std::time::Instant::now();
        }
    }
}

/// CubeCL's autotuning at its `minimal` level unless `CUBECL_AUTOTUNE_LEVEL` says otherwise:
/// at the default level, on an NVIDIA H200, tuning a whole-image step panicked (a candidate's
/// grid over wgpu's 65,535 limit) and then hung, and on lavapipe a first step did not finish in
/// ten minutes (docs/results/gpu-training.md). Takes effect only before CubeCL's first use.
#[cfg(feature = "gpu")]
fn minimal_autotune() {
    use burn_cubecl::cubecl::config::autotune::AutotuneLevel;
    use burn_cubecl::cubecl::config::{CubeClRuntimeConfig, RuntimeConfig};
    if std::env::var_os("CUBECL_AUTOTUNE_LEVEL").is_none() {
        let mut config = CubeClRuntimeConfig::default().override_from_env();
        config.autotune.level = AutotuneLevel::Minimal;
        CubeClRuntimeConfig::try_set(config);
    }
}
