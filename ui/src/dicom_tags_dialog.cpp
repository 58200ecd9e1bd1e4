// The DICOM tag browser (Study ▸ DICOM tags…).
#include <fvr/ui/dicom_tags_dialog.h>

#include <QComboBox>
#include <QDialogButtonBox>
#include <QFormLayout>
#include <QHeaderView>
#include <QLabel>
#include <QLineEdit>
#include <QRegularExpression>
#include <QTreeWidget>
#include <QVBoxLayout>

#include <fvr/core/dicom/multiframe_export.h>

namespace fvr::ui {

DicomTagsDialog::DicomTagsDialog(QWidget* parent) : QDialog(parent) {
    setWindowTitle(tr("DICOM tags"));
    setObjectName("dialog.dicomTags");
    m_instance = new QComboBox;
    m_instance->setObjectName("tags.instance");
    m_filter = new QLineEdit;
    m_filter->setObjectName("tags.filter");
    m_filter->setPlaceholderText(tr("Tag, keyword or value (e.g. 0010, PatientName, 512)"));
    m_filter->setClearButtonEnabled(true);
    m_tree = new QTreeWidget;
    m_tree->setObjectName("tags.tree");
    m_tree->setColumnCount(4);
    m_tree->setHeaderLabels({tr("Tag"), tr("Keyword"), tr("VR"), tr("Value")});
    m_tree->setRootIsDecorated(false);
    m_tree->setUniformRowHeights(true);
    m_tree->setAlternatingRowColors(true);
    m_tree->header()->setSectionResizeMode(QHeaderView::Interactive);
    m_status = new QLabel;
    auto* form = new QFormLayout;
    form->addRow(tr("Instance:"), m_instance);
    form->addRow(tr("Search:"), m_filter);
    auto* buttons = new QDialogButtonBox(QDialogButtonBox::Close);
    connect(buttons, &QDialogButtonBox::rejected, this, &QDialog::reject);
    auto* layout = new QVBoxLayout(this);
    layout->addLayout(form);
    layout->addWidget(m_tree, 1);
    layout->addWidget(m_status);
    layout->addWidget(buttons);
    connect(m_instance, &QComboBox::currentIndexChanged, this, &DicomTagsDialog::showInstance);
    connect(m_filter, &QLineEdit::textChanged, this, [this] { applyFilter(); });
    resize(820, 640);
}

void DicomTagsDialog::setFiles(const std::vector<std::filesystem::path>& files,
                               const QString& seriesName) {
    m_files = files;
    setWindowTitle(seriesName.isEmpty() ? tr("DICOM tags") : tr("DICOM tags: %1").arg(seriesName));
    {
        const QSignalBlocker block(m_instance);
        m_instance->clear();
        for (std::size_t i = 0; i < files.size(); ++i)
            m_instance->addItem(tr("%1 of %2: %3")
                                    .arg(i + 1)
                                    .arg(files.size())
                                    .arg(QString::fromStdString(files[i].filename().string())));
    }
    if (files.empty()) {
        m_tree->clear();
        m_error = tr("The open study is not DICOM (a phantom or a volume file): it has no tags.");
        m_status->setText(m_error);
        return;
    }
    showInstance(0);
}

void DicomTagsDialog::showInstance(int index) {
    if (index < 0 || index >= int(m_files.size())) return;
    if (m_instance->currentIndex() != index) {
        const QSignalBlocker block(m_instance);
        m_instance->setCurrentIndex(index);
    }
    m_tree->clear();
    m_error.clear();
    std::vector<core::DicomTagRow> rows;
    try {
        rows = core::readDicomTags(m_files[std::size_t(index)]);
    } catch (const std::exception& e) {
        m_error = QString::fromUtf8(e.what());
    }
    QList<QTreeWidgetItem*> items;
    items.reserve(qsizetype(rows.size()));
    for (const core::DicomTagRow& r : rows) {
        // Items of a sequence are indented under it (the keyword column shows the depth).
        const QString indent(2 * r.depth, QLatin1Char(' '));
        items.append(new QTreeWidgetItem(
            QStringList{QString::fromStdString(r.tag), indent + QString::fromStdString(r.keyword),
                        QString::fromStdString(r.vr), QString::fromUtf8(r.value.c_str())}));
    }
    m_tree->addTopLevelItems(items);
    for (int c = 0; c < 3; ++c) m_tree->resizeColumnToContents(c);
    applyFilter();
}

void DicomTagsDialog::setFilter(const QString& text) { m_filter->setText(text); }

void DicomTagsDialog::applyFilter() {
    const QString f = m_filter->text().trimmed();
    int shown = 0;
    // A tag matches typed with or without its brackets and comma ("00100010", "0010,0010").
    static const QRegularExpression punctuation("[(), ]");
    const QString fTag = QString(f).remove(punctuation);
    for (int i = 0; i < m_tree->topLevelItemCount(); ++i) {
        QTreeWidgetItem* it = m_tree->topLevelItem(i);
        bool match =
            f.isEmpty() || (!fTag.isEmpty() &&
                            it->text(0).remove(punctuation).contains(fTag, Qt::CaseInsensitive));
        for (int c = 1; c < 4 && !match; ++c) match = it->text(c).contains(f, Qt::CaseInsensitive);
        it->setHidden(!match);
        shown += match;
    }
    if (m_error.isEmpty())
        m_status->setText(tr("%1 of %2 elements").arg(shown).arg(m_tree->topLevelItemCount()));
    else
        m_status->setText(m_error);
}

QStringList DicomTagsDialog::visibleRows() const {
    QStringList out;
    for (int i = 0; i < m_tree->topLevelItemCount(); ++i) {
        const QTreeWidgetItem* it = m_tree->topLevelItem(i);
        if (!it->isHidden()) out << it->text(1).trimmed() + "=" + it->text(3);
    }
    return out;
}

} // namespace fvr::ui
