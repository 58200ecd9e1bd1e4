#pragma once
/** The Messages panel: a read-only log, one time-stamped line per message. */
#include <QPlainTextEdit>

namespace fvr::ui {

class MessagesPanel : public QPlainTextEdit {
    Q_OBJECT
public:
    explicit MessagesPanel(QWidget* parent = nullptr);
    /** Appends "HH:mm:ss  text". */
    void add(const QString& text);
};

} // namespace fvr::ui
