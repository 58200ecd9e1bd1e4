// The local study store, the storage listener and sends on worker threads.
#include <fvr/ui/pacs_service.h>

#include <fvr/ui/pacs_settings.h>
#include <fvr/ui/study.h>

namespace fvr::ui {

namespace pacs = core::pacs;

PacsService::PacsService(std::filesystem::path storeRoot, QObject* parent)
    : QObject(parent),
      m_store(std::make_shared<pacs::LocalStore>(storeRoot.empty() ? pacs::defaultLocalStoreRoot()
                                                                   : std::move(storeRoot))),
      m_retrieves(std::make_unique<RetrieveQueue>(m_store)) {}

PacsService::~PacsService() {
    m_retrieves.reset(); // cancelled and waited for first: a C-MOVE may use the listener
    if (m_listener) m_listener->stop();
    m_jobs.wait(); // sends cannot be cancelled; their files are removed when they end
}

QString PacsService::applyListener(const PacsSettings& s, bool* ok) {
    if (ok) *ok = true;
    const bool same = m_listener && m_listener->local().aeTitle == s.local.aeTitle &&
                      m_listener->local().listenPort == s.local.listenPort &&
                      m_listener->local().listenAddress == s.local.listenAddress &&
                      m_listener->local().allowedPeers == s.local.allowedPeers &&
                      m_listener->local().listenTls == s.local.listenTls &&
                      m_listener->local().tls == s.local.tls &&
                      m_listener->local().timeoutSeconds == s.local.timeoutSeconds;
    if (!s.listen || !same) {
        const bool was = listening();
        m_listener.reset(); // stops it
        if (!s.listen) return was ? tr("Storage listener stopped") : QString();
    }
    if (listening()) return QString();
    try {
        // Events come on the listener's thread: to the UI thread, if we still exist.
        QPointer<PacsService> self(this);
        auto onEvent = [self](const pacs::StorageListener::Event& e) {
            const bool problem = e.kind != pacs::StorageListener::Event::Kind::Incoming;
            const QString text = QString::fromStdString(e.text);
            postToGui(self, [self, problem, text] {
                emit self->listenerEvent(problem, text);
                // Names whose bytes no character set explained, of what just arrived.
                for (const std::string& p : self->m_store->takeTextProblems())
                    emit self->listenerEvent(true, QString::fromStdString(p));
            });
        };
        m_listener = std::make_unique<pacs::StorageListener>(s.local, *m_store, onEvent);
        m_listener->start();
    } catch (const std::exception& e) {
        m_listener.reset();
        if (ok) *ok = false;
        return tr("Storage listener not started: %1").arg(QString::fromUtf8(e.what()));
    }
    QString peers;
    for (const pacs::Peer& p : s.local.allowedPeers)
        peers += (peers.isEmpty() ? "" : ", ") + QString::fromStdString(pacs::describe(p));
    const QString reach = pacs::listensBeyondLoopback(s.local.listenAddress)
                              ? tr(" (reachable from other machines)")
                              : tr(" (this machine only)");
    return tr("Storage listener: listening on port %3 (%1 on %2:%3%6), into %4; takes C-MOVEs we "
              "ask for, and studies "
              "sent by: %5")
        .arg(QString::fromStdString(s.local.aeTitle),
             QString::fromStdString(s.local.listenAddress.empty() ? "0.0.0.0"
                                                                  : s.local.listenAddress))
        .arg(s.local.listenPort)
        .arg(QString::fromStdString(m_store->root().string()),
             peers.isEmpty() ? tr("no one") : peers, reach);
}

void PacsService::send(const pacs::Node& node, const pacs::LocalAe& local,
                       std::vector<std::filesystem::path> files, std::filesystem::path cleanup) {
    ++m_sending;
    const int count = int(files.size());
    const QString peer = QString::fromStdString(pacs::describe(node));
    auto removeCleanup = [cleanup] {
        std::error_code ec;
        if (!cleanup.empty()) std::filesystem::remove_all(cleanup, ec);
    };
    m_jobs.run(
        [node, local, files = std::move(files), removeCleanup](core::CancelToken&) {
            try {
                pacs::sendFiles(node, local, files);
            } catch (...) {
                removeCleanup();
                throw;
            }
            removeCleanup();
        },
        [this, count, peer] {
            --m_sending;
            emit sent(
                true,
                tr("Sent %1 to %2").arg(countOf(count, tr("1 image"), tr("%1 images")), peer));
        },
        [this](const JobError& e) {
            --m_sending;
            emit sent(false, tr("Send failed: %1").arg(e.message));
        });
}

} // namespace fvr::ui
