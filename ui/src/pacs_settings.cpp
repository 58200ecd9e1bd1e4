// PACS nodes, our AE title and the storage listener in the settings; the dialog that edits them.
#include <fvr/ui/pacs_settings.h>

#include <QCheckBox>
#include <QComboBox>
#include <QDialogButtonBox>
#include <QFileDialog>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QSettings>
#include <QSpinBox>
#include <QTableWidget>
#include <QToolButton>
#include <QVBoxLayout>

#include <fvr/ui/settings_keys.h>

namespace fvr::ui {

namespace {

using core::pacs::Node;
using core::pacs::RetrieveMethod;

enum Column { kName, kCalledAe, kHost, kPort, kTls, kRetrieve, kColumns };

QString text(const std::string& s) { return QString::fromStdString(s); }

/** The allowed peers as the dialog shows them: "AE, AE@host". */
QString peersText(const std::vector<core::pacs::Peer>& peers) {
    QStringList out;
    for (const core::pacs::Peer& p : peers) out << text(core::pacs::describe(p));
    return out.join(QStringLiteral(", "));
}

/** The dialog's "AE, AE@host" as peers; `problems` gets the ones parsePeer() refuses. */
std::vector<core::pacs::Peer> parsePeers(const QString& list, QStringList* problems) {
    std::vector<core::pacs::Peer> out;
    for (const QString& item : list.split(QLatin1Char(','), Qt::SkipEmptyParts)) {
        if (item.trimmed().isEmpty()) continue;
        try {
            out.push_back(core::pacs::parsePeer(item.trimmed().toStdString()));
        } catch (const std::exception& e) {
            if (problems) *problems << QString::fromUtf8(e.what());
        }
    }
    return out;
}

/** The TLS settings (ours for every node with TLS on, and for the listener). */
void loadTls(QSettings& s, core::pacs::LocalAe& local) {
    local.tls.certificateFile = s.value(keys::kPacsTlsCertificate).toString().toStdString();
    local.tls.privateKeyFile = s.value(keys::kPacsTlsPrivateKey).toString().toStdString();
    local.tls.trustedCaFiles.clear();
    for (const QString& f : s.value(keys::kPacsTlsTrustedCa).toStringList())
        local.tls.trustedCaFiles.push_back(f.toStdString());
    local.tls.verifyPeer = s.value(keys::kPacsTlsVerifyPeer, true).toBool();
    local.listenTls = s.value(keys::kPacsListenTls, false).toBool();
}

void saveTls(QSettings& s, const core::pacs::LocalAe& local) {
    s.setValue(keys::kPacsTlsCertificate, text(local.tls.certificateFile));
    s.setValue(keys::kPacsTlsPrivateKey, text(local.tls.privateKeyFile));
    QStringList ca;
    for (const std::string& f : local.tls.trustedCaFiles) ca << text(f);
    s.setValue(keys::kPacsTlsTrustedCa, ca);
    s.setValue(keys::kPacsTlsVerifyPeer, local.tls.verifyPeer);
    s.setValue(keys::kPacsListenTls, local.listenTls);
}

/** A path field with a "…" button that picks a PEM file. */
QWidget* fileField(QLineEdit* edit, const QString& title, QWidget* parent) {
    auto* box = new QWidget(parent);
    auto* row = new QHBoxLayout(box);
    row->setContentsMargins(0, 0, 0, 0);
    row->addWidget(edit);
    auto* browse = new QToolButton(box);
    browse->setText(QStringLiteral("…"));
    QObject::connect(browse, &QToolButton::clicked, box, [edit, title, box] {
        const QString f = QFileDialog::getOpenFileName(
            box, title, QString(), QObject::tr("PEM files (*.pem *.crt *.key);;All files (*)"));
        if (f.isEmpty()) return;
        const bool list = edit->property("list").toBool(); // several files, ';'-separated
        edit->setText(list && !edit->text().trimmed().isEmpty() ? edit->text() + ";" + f : f);
    });
    row->addWidget(browse);
    return box;
}

} // namespace

PacsSettings PacsSettings::load() {
    QSettings s;
    PacsSettings p;
    const int n = s.beginReadArray(keys::kPacsNodes);
    for (int i = 0; i < n; ++i) {
        s.setArrayIndex(i);
        Node node;
        node.name = s.value("name").toString().toStdString();
        node.calledAe = s.value("calledAe").toString().toStdString();
        node.host = s.value("host").toString().toStdString();
        node.port = s.value("port", 104).toInt();
        node.retrieve = s.value("retrieve").toString() == QLatin1String("move")
                            ? RetrieveMethod::Move
                            : RetrieveMethod::Get;
        node.tls = s.value("tls", false).toBool();
        p.nodes.push_back(node);
    }
    s.endArray();
    p.local.aeTitle = s.value(keys::kPacsAeTitle, text(p.local.aeTitle)).toString().toStdString();
    p.local.listenPort = s.value(keys::kPacsListenPort, p.local.listenPort).toInt();
    p.local.timeoutSeconds = s.value(keys::kPacsTimeout, p.local.timeoutSeconds).toInt();
    p.listen = s.value(keys::kPacsListen, false).toBool();
    p.local.listenAddress =
        s.value(keys::kPacsListenAddress, text(p.local.listenAddress)).toString().toStdString();
    for (const QString& peer : s.value(keys::kPacsAllowedPeers).toStringList()) {
        try {
            p.local.allowedPeers.push_back(core::pacs::parsePeer(peer.toStdString()));
        } catch (const std::exception&) {
            // Edited by hand into something invalid: not trusted (the dialog shows the rest).
        }
    }
    loadTls(s, p.local);
    return p;
}

void PacsSettings::save() const {
    QSettings s;
    s.beginWriteArray(keys::kPacsNodes, int(nodes.size()));
    for (int i = 0; i < int(nodes.size()); ++i) {
        s.setArrayIndex(i);
        const Node& n = nodes[std::size_t(i)];
        s.setValue("name", text(n.name));
        s.setValue("calledAe", text(n.calledAe));
        s.setValue("host", text(n.host));
        s.setValue("port", n.port);
        s.setValue("retrieve", n.retrieve == RetrieveMethod::Move ? "move" : "get");
        s.setValue("tls", n.tls);
    }
    s.endArray();
    s.setValue(keys::kPacsAeTitle, text(local.aeTitle));
    s.setValue(keys::kPacsListenPort, local.listenPort);
    s.setValue(keys::kPacsTimeout, local.timeoutSeconds);
    s.setValue(keys::kPacsListen, listen);
    s.setValue(keys::kPacsListenAddress, text(local.listenAddress));
    QStringList peers;
    for (const core::pacs::Peer& p : local.allowedPeers) peers << text(core::pacs::describe(p));
    s.setValue(keys::kPacsAllowedPeers, peers);
    saveTls(s, local);
}

const Node* PacsSettings::node(const QString& name) const {
    for (const Node& n : nodes)
        if (text(n.name) == name) return &n;
    return nodes.empty() ? nullptr : &nodes.front();
}

PacsNodesDialog::PacsNodesDialog(const PacsSettings& settings, QWidget* parent) : QDialog(parent) {
    setWindowTitle(tr("PACS nodes"));
    auto* layout = new QVBoxLayout(this);
    m_table = new QTableWidget(0, kColumns, this);
    m_table->setHorizontalHeaderLabels({tr("Name"), tr("Called AE title"), tr("Host"), tr("Port"),
                                        tr("TLS"), tr("Retrieve with")});
    m_table->horizontalHeader()->setStretchLastSection(true);
    m_table->setToolTip(tr("C-GET needs no listener; C-MOVE sends the images to our storage "
                           "listener, which the PACS must know by our AE title, host and port"));
    for (const Node& n : settings.nodes) addRow(n);
    layout->addWidget(m_table);
    auto* rowButtons = new QDialogButtonBox(this);
    QPushButton* add = rowButtons->addButton(tr("Add node"), QDialogButtonBox::ActionRole);
    QPushButton* remove = rowButtons->addButton(tr("Remove node"), QDialogButtonBox::ActionRole);
    connect(add, &QPushButton::clicked, this, [this] {
        Node n;
        n.name = "PACS";
        n.calledAe = "ORTHANC";
        n.host = "localhost";
        n.port = 4242;
        addRow(n);
    });
    connect(remove, &QPushButton::clicked, this, [this] {
        if (m_table->currentRow() >= 0) m_table->removeRow(m_table->currentRow());
    });
    layout->addWidget(rowButtons);

    auto* form = new QFormLayout;
    m_aeTitle = new QLineEdit(text(settings.local.aeTitle), this);
    m_aeTitle->setMaxLength(16);
    form->addRow(tr("Our AE title"), m_aeTitle);
    m_port = new QSpinBox(this);
    m_port->setRange(1, 65535);
    m_port->setValue(settings.local.listenPort);
    form->addRow(tr("Listener port"), m_port);
    m_listenAddress = new QLineEdit(text(settings.local.listenAddress), this);
    m_listenAddress->setToolTip(tr("The address the listener binds: 127.0.0.1 takes connections "
                                   "from this machine only; 0.0.0.0 from every interface (a PACS "
                                   "on another machine)"));
    form->addRow(tr("Listener address"), m_listenAddress);
    m_allowedPeers = new QLineEdit(peersText(settings.local.allowedPeers), this);
    m_allowedPeers->setPlaceholderText(tr("none (AE or AE@host, comma-separated)"));
    m_allowedPeers->setToolTip(tr("Who may send us studies unasked (they go to the store's "
                                  "Incoming area). The nodes above need not be listed: each is "
                                  "trusted for the C-MOVEs we ask it for, and for nothing else"));
    form->addRow(tr("Accept studies sent by"), m_allowedPeers);
    m_timeout = new QSpinBox(this);
    m_timeout->setRange(1, 600);
    m_timeout->setSuffix(tr(" s"));
    m_timeout->setValue(settings.local.timeoutSeconds);
    form->addRow(tr("Network timeout"), m_timeout);
    m_listen = new QCheckBox(tr("Run the storage listener (receives C-MOVE and sent studies)"));
    m_listen->setChecked(settings.listen);
    form->addRow(QString(), m_listen);
    addTlsRows(form, settings.local);
    layout->addLayout(form);
    m_error = new QLabel(this);
    m_error->setStyleSheet(QStringLiteral("color: #c0392b"));
    m_error->setWordWrap(true);
    m_error->setVisible(false);
    layout->addWidget(m_error);
    auto* buttons = new QDialogButtonBox(QDialogButtonBox::Ok | QDialogButtonBox::Cancel, this);
    connect(buttons, &QDialogButtonBox::accepted, this, &PacsNodesDialog::accept);
    connect(buttons, &QDialogButtonBox::rejected, this, &QDialog::reject);
    layout->addWidget(buttons);
    resize(760, 480);
}

void PacsNodesDialog::addTlsRows(QFormLayout* form, const core::pacs::LocalAe& local) {
    m_tlsCert = new QLineEdit(text(local.tls.certificateFile), this);
    m_tlsCert->setPlaceholderText(tr("PEM file: shown to the PACS and by a TLS listener"));
    form->addRow(tr("TLS certificate"), fileField(m_tlsCert, tr("Our TLS certificate"), this));
    m_tlsKey = new QLineEdit(text(local.tls.privateKeyFile), this);
    m_tlsKey->setPlaceholderText(tr("PEM file, not encrypted"));
    form->addRow(tr("TLS private key"), fileField(m_tlsKey, tr("Its private key"), this));
    QStringList ca;
    for (const std::string& f : local.tls.trustedCaFiles) ca << text(f);
    m_tlsCa = new QLineEdit(ca.join(QLatin1Char(';')), this);
    m_tlsCa->setProperty("list", true);
    m_tlsCa->setPlaceholderText(tr("PEM files, separated by ;"));
    form->addRow(tr("Trusted CAs"), fileField(m_tlsCa, tr("A CA certificate we trust"), this));
    m_tlsVerify = new QCheckBox(tr("Refuse a peer whose certificate these CAs did not sign"));
    m_tlsVerify->setChecked(local.tls.verifyPeer);
    form->addRow(QString(), m_tlsVerify);
    m_listenTls = new QCheckBox(tr("The listener speaks DICOM TLS (only)"));
    m_listenTls->setChecked(local.listenTls);
    form->addRow(QString(), m_listenTls);
}

void PacsNodesDialog::addRow(const Node& n) {
    const int row = m_table->rowCount();
    m_table->insertRow(row);
    m_table->setItem(row, kName, new QTableWidgetItem(text(n.name)));
    m_table->setItem(row, kCalledAe, new QTableWidgetItem(text(n.calledAe)));
    m_table->setItem(row, kHost, new QTableWidgetItem(text(n.host)));
    auto* port = new QSpinBox(m_table);
    port->setRange(1, 65535);
    port->setValue(n.port);
    m_table->setCellWidget(row, kPort, port);
    auto* tls = new QTableWidgetItem;
    tls->setFlags(Qt::ItemIsUserCheckable | Qt::ItemIsEnabled | Qt::ItemIsSelectable);
    tls->setCheckState(n.tls ? Qt::Checked : Qt::Unchecked);
    tls->setToolTip(tr("DICOM TLS to this node, with our certificate and trusted CAs below"));
    m_table->setItem(row, kTls, tls);
    auto* retrieve = new QComboBox(m_table);
    retrieve->addItems({tr("C-GET"), tr("C-MOVE")});
    retrieve->setCurrentIndex(n.retrieve == RetrieveMethod::Move ? 1 : 0);
    m_table->setCellWidget(row, kRetrieve, retrieve);
}

PacsSettings PacsNodesDialog::settings() const {
    PacsSettings p;
    for (int row = 0; row < m_table->rowCount(); ++row) {
        Node n;
        auto cell = [&](int c) {
            const QTableWidgetItem* item = m_table->item(row, c);
            return item ? item->text().trimmed().toStdString() : std::string();
        };
        n.name = cell(kName);
        n.calledAe = cell(kCalledAe);
        n.host = cell(kHost);
        n.port = static_cast<QSpinBox*>(m_table->cellWidget(row, kPort))->value();
        n.retrieve = static_cast<QComboBox*>(m_table->cellWidget(row, kRetrieve))->currentIndex()
                         ? RetrieveMethod::Move
                         : RetrieveMethod::Get;
        const QTableWidgetItem* tls = m_table->item(row, kTls);
        n.tls = tls && tls->checkState() == Qt::Checked;
        p.nodes.push_back(n);
    }
    p.local.aeTitle = m_aeTitle->text().trimmed().toStdString();
    p.local.listenPort = m_port->value();
    p.local.timeoutSeconds = m_timeout->value();
    p.listen = m_listen->isChecked();
    p.local.listenAddress = m_listenAddress->text().trimmed().toStdString();
    p.local.allowedPeers = parsePeers(m_allowedPeers->text(), nullptr);
    p.local.tls.certificateFile = m_tlsCert->text().trimmed().toStdString();
    p.local.tls.privateKeyFile = m_tlsKey->text().trimmed().toStdString();
    for (const QString& f : m_tlsCa->text().split(QLatin1Char(';'), Qt::SkipEmptyParts))
        if (!f.trimmed().isEmpty()) p.local.tls.trustedCaFiles.push_back(f.trimmed().toStdString());
    p.local.tls.verifyPeer = m_tlsVerify->isChecked();
    p.local.listenTls = m_listenTls->isChecked();
    return p;
}

void PacsNodesDialog::accept() {
    const PacsSettings p = settings();
    QStringList problems;
    auto check = [&](auto&& validate) {
        try {
            validate();
        } catch (const std::exception& e) {
            problems << QString::fromUtf8(e.what());
        }
    };
    check([&] { core::pacs::validateListener(p.local); }); // validate(p.local) and more
    parsePeers(m_allowedPeers->text(), &problems);
    bool tls = p.local.listenTls;
    for (const Node& n : p.nodes) {
        if (n.name.empty()) problems << tr("A node has no name.");
        check([&] { core::pacs::validate(n); });
        tls = tls || n.tls;
    }
    if (tls) check([&] { core::pacs::checkTls(p.local); }); // the files, as a connection reads them
    m_error->setText(problems.join(QLatin1Char('\n')));
    m_error->setVisible(!problems.isEmpty());
    if (!problems.isEmpty()) return;
    QDialog::accept();
}

} // namespace fvr::ui
