#include <fvr/ui/panels/messages_panel.h>

#include <QTime>

namespace fvr::ui {

MessagesPanel::MessagesPanel(QWidget* parent) : QPlainTextEdit(parent) {
    setReadOnly(true);
    setMaximumBlockCount(2000);
}

void MessagesPanel::add(const QString& text) {
    appendPlainText(QStringLiteral("%1  %2").arg(QTime::currentTime().toString("HH:mm:ss"), text));
}

} // namespace fvr::ui
