#pragma once
/** The Study panel: what the open study is (name, dimensions, spacing, values, spectrum) and its
 *  warnings, as selectable text that scrolls. */
#include <QScrollArea>

class QLabel;

namespace fvr::ui {

class StudyController;

class StudyPanel : public QScrollArea {
    Q_OBJECT
public:
    explicit StudyPanel(QWidget* parent = nullptr);
    /** Describes the controller's study ("No study" when none is open). */
    void showStudy(const StudyController& study);
    /** The text on show (rich text). */
    QString text() const;

private:
    QLabel* m_info = nullptr;
};

} // namespace fvr::ui
