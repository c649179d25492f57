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

/// The Mesa release (major, minor) of the first Vulkan adapter's driver (lavapipe's
/// driver info reads e.g. "Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)"), or `None` when the
/// adapter is not Mesa's or there is none.
pub fn mesa_version() -> Option<(u32, u32)> {
    parse_mesa_version(vulkan_adapter()?)
}

fn parse_mesa_version(adapter: &str) -> Option<(u32, u32)> {
    let rest = &adapter[adapter.find("Mesa ")? + "Mesa ".len()..];
    let mut numbers = rest.split(|c: char| !c.is_ascii_digit());
    let major = numbers.next()?.parse().ok()?;
    let minor = numbers.next()?.parse().ok()?;
    Some((major, minor))
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

#[cfg(test)]
mod tests {
    use super::parse_mesa_version;

    #[test]
    fn mesa_versions_parse() {
        let lavapipe = "llvmpipe (LLVM 15.0.6, 256 bits) (Cpu, driver llvmpipe \
                        Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6))";
        assert_eq!(parse_mesa_version(lavapipe), Some((25, 0)));
        let old =
            "llvmpipe (LLVM 15.0.6, 256 bits) (Cpu, driver llvmpipe Mesa 22.3.6 (LLVM 15.0.6))";
        assert_eq!(parse_mesa_version(old), Some((22, 3)));
        assert_eq!(
            parse_mesa_version("NVIDIA H200 (DiscreteGpu, driver NVIDIA 570.1)"),
            None
        );
    }
}
