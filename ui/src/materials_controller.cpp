#include <fvr/ui/materials_controller.h>

#include <fvr/core/xray/polychromatic_render.h>

namespace fvr::ui {

MaterialsController::MaterialsController(QObject* parent) : QObject(parent) {}

MaterialsController::~MaterialsController() = default; // m_jobs cancels and waits

bool MaterialsController::setVolume(std::shared_ptr<const core::Volume> volume) {
    if (volume == m_volume) return false;
    if (m_cancel) m_cancel->cancel(); // a running job's spectra are the old volume's
    m_spectra.clear();
    m_volume = std::move(volume);
    return true;
}

void MaterialsController::prepare(const std::set<int>& keys,
                                  const core::PreprocessOptions& options) {
    if (m_busy || keys.empty() || !m_volume) return;
    m_busy = true;
    core::PreprocessOptions po;
    po.transform = options.transform;
    po.oversampling = options.oversampling;
    const auto vol = m_volume;
    using Prepared = std::map<int, MaterialSpectra>;
    m_cancel = m_jobs.run(
        [vol, po, keys](core::CancelToken& token) {
            Prepared out;
            for (int key : keys) {
                core::PreprocessOptions o = po;
                if (key >= 0) o.deapodizeFor = core::Kernel(key);
                out[key] = core::preprocessMaterials(*vol, core::MaterialMapping{}, o, {}, &token);
            }
            return out;
        },
        [this, vol](Prepared prepared) {
            m_busy = false;
            // Cancelled at its end, or another volume came while it ran.
            if (m_cancel->cancelled() || vol != m_volume) {
                emit discarded();
                return;
            }
            m_spectra.insert(prepared.begin(), prepared.end());
            emit ready();
        },
        [this](const JobError& e) {
            m_busy = false;
            if (e.cancelled())
                emit discarded(); // the new volume's materials are wanted
            else
                emit failed(e.message);
        });
}

double MaterialsController::spectraMiB() const {
    double bytes = 0.0;
    for (const auto& [key, spectra] : m_spectra)
        for (const auto& s : spectra) bytes += double(s->bytes());
    return bytes / (1 << 20);
}

int MaterialsController::spectrumCount() const {
    int count = 0;
    for (const auto& [key, spectra] : m_spectra) count += int(spectra.size());
    return count;
}

} // namespace fvr::ui
