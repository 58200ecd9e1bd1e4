#pragma once
/** The PACS nodes the workstation knows, its own AE title and storage listener: kept in the
 *  settings (keys in settings_keys.h) and edited in PacsNodesDialog. */
#include <QDialog>

#include <vector>

#include <fvr/core/pacs/pacs.h>

class QCheckBox;
class QFormLayout;
class QLabel;
class QLineEdit;
class QSpinBox;
class QTableWidget;

namespace fvr::ui {

struct PacsSettings {
    std::vector<core::pacs::Node> nodes;
    core::pacs::LocalAe local;
    bool listen = false; ///< the storage listener runs (off by default)

    static PacsSettings load();
    void save() const;
    /** The node named `name`, else the first; null when there is none. */
    const core::pacs::Node* node(const QString& name) const;
};

/** Settings ▸ PACS nodes: a table of nodes (name, called AE, host, port, TLS, retrieve method),
 *  our AE title, the listener port, its address, the peers whose own stores it takes (into the
 *  store's Incoming area; the nodes are trusted for their C-MOVEs only) and whether it runs,
 *  and DICOM TLS: our certificate and key, the CAs we trust, the peer check, whether the
 *  listener speaks TLS. */
class PacsNodesDialog : public QDialog {
    Q_OBJECT
public:
    explicit PacsNodesDialog(const PacsSettings& settings, QWidget* parent = nullptr);
    /** What the dialog holds now; the caller saves it after accept(). */
    PacsSettings settings() const;
    QTableWidget* table() const { return m_table; }
    QLineEdit* aeTitleEdit() const { return m_aeTitle; }
    QLineEdit* listenAddressEdit() const { return m_listenAddress; }
    /** The allowed peers, comma-separated "AE" or "AE@host". */
    QLineEdit* allowedPeersEdit() const { return m_allowedPeers; }
    QLineEdit* tlsCertificateEdit() const { return m_tlsCert; }
    QLineEdit* tlsPrivateKeyEdit() const { return m_tlsKey; }
    QLineEdit* tlsTrustedCaEdit() const { return m_tlsCa; } ///< files separated by ';'
    QCheckBox* tlsVerifyBox() const { return m_tlsVerify; }
    QCheckBox* listenTlsBox() const { return m_listenTls; }
    /** Why OK did not close the dialog (invalid AE titles, a node without host). */
    QLabel* errorLabel() const { return m_error; }

    /** OK: closes only when every node and our AE title are valid (else errorLabel() says why). */
    void accept() override;

private:
    void addRow(const core::pacs::Node& n);
    void addTlsRows(QFormLayout* form, const core::pacs::LocalAe& local);

    QTableWidget* m_table = nullptr;
    QLineEdit* m_aeTitle = nullptr;
    QSpinBox* m_port = nullptr;
    QLineEdit* m_listenAddress = nullptr;
    QLineEdit* m_allowedPeers = nullptr;
    QSpinBox* m_timeout = nullptr;
    QCheckBox* m_listen = nullptr;
    QLineEdit* m_tlsCert = nullptr;
    QLineEdit* m_tlsKey = nullptr;
    QLineEdit* m_tlsCa = nullptr;
    QCheckBox* m_tlsVerify = nullptr;
    QCheckBox* m_listenTls = nullptr;
    QLabel* m_error = nullptr;
};

} // namespace fvr::ui
