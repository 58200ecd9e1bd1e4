// The registration's GPU DRR renderer (drr_renderer.h).
#include <fvr/gpu/drr_renderer.h>

namespace fvr::gpu {

namespace {

class GpuDrrRenderer final : public core::DrrRenderer {
public:
    GpuDrrRenderer(const core::Volume& volume, const core::ConeProjectorOptions& options,
                   TrilinearFetch fetch)
        : m_caster(volume, options, fetch) {}
    std::vector<core::DetectorImage> render(const std::vector<core::ConeCamera>& cameras) override {
        return m_caster.projectMany(cameras);
    }
    std::string describe() const override {
        return describeConeRayCaster(m_caster.options(), m_caster.fetch());
    }

private:
    ConeRayCaster m_caster;
};

} // namespace

core::DrrRendererFactory gpuDrrRendererFactory(TrilinearFetch fetch) {
    return [fetch](const core::Volume& volume, const core::ConeProjectorOptions& options) {
        return std::unique_ptr<core::DrrRenderer>(
            std::make_unique<GpuDrrRenderer>(volume, options, fetch));
    };
}

} // namespace fvr::gpu
