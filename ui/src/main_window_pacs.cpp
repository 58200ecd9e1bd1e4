// The main window's PACS actions: the PACS dialog, the nodes, the listener, Send to PACS.
#include <fvr/ui/main_window.h>

#include <QInputDialog>
#include <QMenu>
#include <QMessageBox>
#include <QStatusBar>
#include <QTemporaryDir>

#include <fvr/ui/pacs_dialog.h>
#include <fvr/ui/pacs_service.h>
#include <fvr/ui/pacs_settings.h>
#include <fvr/ui/retrieve_queue.h>
#include <fvr/ui/study.h>

namespace fvr::ui {

namespace {
QString text(const std::string& s) { return QString::fromStdString(s); }
} // namespace

void MainWindow::buildPacsMenu(QMenu* file) {
    m_pacs = std::make_unique<PacsService>();
    connect(m_pacs.get(), &PacsService::sent, this,
            [this](bool ok, const QString& text) { message(text, !ok); });
    connect(m_pacs.get(), &PacsService::listenerEvent, this,
            [this](bool problem, const QString& text) { message(text, problem); });
    RetrieveQueue& retrieves = m_pacs->retrieves();
    connect(&retrieves, &RetrieveQueue::message, this, &MainWindow::message);
    connect(&retrieves, &RetrieveQueue::ended, this, [this](int id) {
        const RetrieveJob* j = m_pacs->retrieves().job(id);
        // Opened only when asked with "Retrieve and open" and nothing was opened since: a
        // retrieve that ends later never replaces what the user went on to read.
        if (j && m_pacs->retrieves().shouldOpen(*j))
            openStudy(StudySource::fromPath(QString::fromStdString(j->folder.string())));
        else if (j && j->open && j->state == RetrieveJob::State::Done)
            message(tr("%1 is in the local store and was not opened, another study being open "
                       "since: File ▸ PACS ▸ Local studies opens it")
                        .arg(j->label));
        else if (j && j->openSuperseded && j->state == RetrieveJob::State::Done)
            message(tr("%1 is in the local store and was not opened: a later Retrieve and open "
                       "asked for another study")
                        .arg(j->label));
    });
    auto* status = new RetrieveStatus(retrieves, this);
    statusBar()->addPermanentWidget(status);
    connect(status, &RetrieveStatus::showQueue, this, [this] {
        PacsDialog* d = pacsDialog();
        d->showQueue();
        d->show();
        d->raise();
        d->activateWindow();
    });
    QAction* open = file->addAction(tr("&PACS: search and retrieve…"), this, [this] {
        PacsDialog* d = pacsDialog();
        d->show();
        d->raise();
        d->activateWindow();
    });
    open->setShortcut(QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_P));
    QAction* send =
        file->addAction(tr("Send projection to P&ACS…"), this, &MainWindow::sendProjectionDialog);
    send->setEnabled(false); // nothing to send before a study is open
    connect(m_study.get(), &StudyController::studyLoaded, send, [send] { send->setEnabled(true); });
    file->addAction(tr("PACS &nodes and listener…"), this, &MainWindow::editPacsNodes);
    const PacsSettings s = PacsSettings::load();
    if (s.listen) { // off by default; a port in use says so instead of failing the start
        bool ok = true;
        const QString what = m_pacs->applyListener(s, &ok);
        message(what, !ok);
    }
}

PacsDialog* MainWindow::pacsDialog() {
    if (!m_pacsDialog) {
        m_pacsDialog = new PacsDialog(m_pacs->retrieves(), this);
        connect(m_pacsDialog, &PacsDialog::openRequested, this,
                [this](const QString& folder) { openStudy(StudySource::fromPath(folder)); });
        connect(m_pacsDialog, &PacsDialog::message, this, &MainWindow::message);
        connect(m_pacsDialog, &PacsDialog::settingsChanged, this, [this] {
            bool ok = true; // the listener on or off at once, not at the next start
            const QString what = m_pacs->applyListener(PacsSettings::load(), &ok);
            if (!what.isEmpty()) message(what, !ok);
        });
    }
    return m_pacsDialog;
}

bool MainWindow::confirmQuitDuringRetrieves() {
    const RetrieveQueue& q = m_pacs->retrieves();
    if (!q.busy()) return true;
    const int n = q.waiting() + (q.running() ? 1 : 0);
    QMessageBox ask(QMessageBox::Question, tr("Quit during retrieves"),
                    countOf(n, tr("A PACS retrieve is running."),
                            tr("%1 PACS retrieves are running or waiting.")) +
                        tr(" Quit anyway?") + QStringLiteral("\n\n") +
                        tr("What arrived is kept as partial studies: File ▸ PACS ▸ Local studies "
                           "▸ Resume retrieve completes them later."),
                    QMessageBox::Yes | QMessageBox::No, this);
    ask.setObjectName(QStringLiteral("confirmQuitRetrieves"));
    ask.setDefaultButton(QMessageBox::No);
    return ask.exec() == QMessageBox::Yes;
}

void MainWindow::editPacsNodes() {
    PacsNodesDialog d(PacsSettings::load(), this);
    if (d.exec() != QDialog::Accepted) return;
    const PacsSettings s = d.settings();
    s.save();
    bool ok = true;
    const QString what = m_pacs->applyListener(s, &ok);
    if (!what.isEmpty()) message(what, !ok);
    if (m_pacsDialog) m_pacsDialog->reloadSettings();
}

void MainWindow::sendProjectionDialog() {
    const PacsSettings s = PacsSettings::load();
    if (s.nodes.empty()) {
        message(tr("No PACS node to send to: File ▸ PACS nodes and listener… adds one"), true);
        return;
    }
    QStringList names;
    for (const core::pacs::Node& n : s.nodes)
        names << QStringLiteral("%1 (%2)").arg(text(n.name), text(core::pacs::describe(n)));
    int chosen = 0;
    if (names.size() > 1) {
        bool ok = false;
        const QString item = QInputDialog::getItem(this, tr("Send projection to PACS"), tr("Node"),
                                                   names, 0, false, &ok);
        if (!ok) return;
        chosen = int(names.indexOf(item));
    }
    sendProjection(s.nodes[std::size_t(std::max(0, chosen))]);
}

bool MainWindow::sendProjection(const core::pacs::Node& node) {
    QTemporaryDir dir;
    if (!dir.isValid()) {
        message(tr("Send to PACS: no temporary folder (%1)").arg(dir.errorString()), true);
        return false;
    }
    dir.setAutoRemove(false); // the send's worker removes it when done
    const std::filesystem::path folder = dir.path().toStdString();
    const std::filesystem::path file = folder / "projection.dcm";
    try {
        writeDicomProjection(file.string());
    } catch (const std::exception& e) {
        std::error_code ec;
        std::filesystem::remove_all(folder, ec);
        message(tr("Send to PACS: %1").arg(QString::fromUtf8(e.what())), true);
        return false;
    }
    message(tr("Sending the projection to %1…").arg(text(core::pacs::describe(node))));
    m_pacs->send(node, PacsSettings::load().local, {file}, folder);
    return true;
}

} // namespace fvr::ui
