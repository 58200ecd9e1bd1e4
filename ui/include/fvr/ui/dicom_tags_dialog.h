#pragma once
/** Study ▸ DICOM tags…: the header of one instance of the open series (the first by default;
 *  a combo picks another), every element with its tag, keyword, VR and value, sequences with
 *  their items indented. A filter narrows the rows to those whose tag, keyword or value holds
 *  the text (case-insensitive). */
#include <QDialog>

#include <filesystem>
#include <vector>

class QComboBox;
class QLabel;
class QLineEdit;
class QTreeWidget;

namespace fvr::ui {

class DicomTagsDialog : public QDialog {
    Q_OBJECT
public:
    explicit DicomTagsDialog(QWidget* parent = nullptr);
    /** The series' files (in the series' order); shows the first. Empty: says there is no
     *  DICOM study (a phantom or a volume file). */
    void setFiles(const std::vector<std::filesystem::path>& files, const QString& seriesName);
    /** Shows instance `index` (0-based) of the files. */
    void showInstance(int index);
    void setFilter(const QString& text);

    QComboBox* instanceCombo() const { return m_instance; }
    QLineEdit* filterEdit() const { return m_filter; }
    QTreeWidget* tree() const { return m_tree; }
    /** The rows the filter leaves, as "keyword=value" (tests). */
    QStringList visibleRows() const;
    /** The problem reading the instance shown, empty when it was read. */
    const QString& error() const { return m_error; }

private:
    void applyFilter();

    std::vector<std::filesystem::path> m_files;
    QComboBox* m_instance = nullptr;
    QLineEdit* m_filter = nullptr;
    QTreeWidget* m_tree = nullptr;
    QLabel* m_status = nullptr;
    QString m_error;
};

} // namespace fvr::ui
