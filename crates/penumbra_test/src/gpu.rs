//! Probing for a Vulkan adapter, and the skip-or-fail rule for GPU tests.

use std::sync::OnceLock;

/// Name, driver and device type of the first Vulkan adapter, or `None` when there is
/// none (no Vulkan loader, or no ICD such as Mesa's lavapipe). Probed once per process.
pub fn vulkan_adapter() -> Option<&'static str> {
    static ADAPTER: OnceLock<Option<String>> = OnceLock::new();
    ADAPTER
        .get_or_init(|| {
            let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
                backends: wgpu::Backends::VULKAN,
                ..wgpu::InstanceDescriptor::new_without_display_handle()
            });
            let adapters =
                bevy::tasks::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
            adapters.first().map(|a| {
                let info = a.get_info();
                format!(
                    "{} ({:?}, driver {} {})",
                    info.name, info.device_type, info.driver, info.driver_info
                )
            })
        })
        .as_deref()
}

pub use penumbra_testkit::is_ci;

/// Call at the top of every GPU test: returns `true` when a Vulkan adapter exists.
/// Without one it reports the test as skipped ([`penumbra_testkit::skip`]: counted as
/// skipped by `cargo xtask test`) and returns `false` (the test should return early),
/// except under CI, where a missing adapter is a failure, never a skip.
pub fn gpu_or_skip(test: &str) -> bool {
    if vulkan_adapter().is_some() {
        return true;
    }
    penumbra_testkit::skip(
        test,
        "no Vulkan adapter: install Mesa's software Vulkan driver, Debian package \
         `mesa-vulkan-drivers` (or run `cargo xtask test`, which installs it)",
    );
    false
}
