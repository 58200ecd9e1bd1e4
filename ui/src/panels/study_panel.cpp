#include <fvr/ui/panels/study_panel.h>

#include <QLabel>

#include <algorithm>

#include <fvr/ui/study.h>

namespace fvr::ui {

StudyPanel::StudyPanel(QWidget* parent) : QScrollArea(parent) {
    m_info = new QLabel(tr("No study"), this);
    m_info->setWordWrap(true);
    m_info->setTextInteractionFlags(Qt::TextSelectableByMouse);
    m_info->setAlignment(Qt::AlignTop | Qt::AlignLeft);
    m_info->setMargin(6);
    setWidget(m_info);
    setWidgetResizable(true);
    setFrameShape(QFrame::NoFrame);
    setMinimumHeight(170);
}

QString StudyPanel::text() const { return m_info->text(); }

namespace {

/** Patient, study and series of a DICOM study, one line each. */
QString seriesLines(const core::DicomSeriesInfo& s) {
    auto esc = [](const std::string& v) { return QString::fromStdString(v).toHtmlEscaped(); };
    QString html;
    if (!s.patientName.empty() || !s.patientId.empty())
        html += StudyPanel::tr("Patient: %1%2<br>")
                    .arg(personName(s.patientName).toHtmlEscaped(),
                         s.patientId.empty() ? QString()
                                             : QStringLiteral(" (%1)").arg(esc(s.patientId)));
    if (!s.studyDate.empty() || !s.modality.empty())
        html += StudyPanel::tr("Study: %1 %2<br>")
                    .arg(dicomDate(s.studyDate).toHtmlEscaped(), esc(s.modality));
    if (!s.description.empty()) html += StudyPanel::tr("Series: %1<br>").arg(esc(s.description));
    return html;
}

/** The panel's heading. A folder of the local store is named by its study (or series) UID, which
 *  says nothing and, one word without a space, cannot wrap: the study's title heads then, and
 *  the UID follows on a line of its own that may wrap after its dots (zero-width spaces). */
QString heading(const StudyController& study) {
    const QString name = study.source().displayName();
    const bool uid = !name.isEmpty() && std::all_of(name.begin(), name.end(), [](QChar c) {
        return c.isDigit() || c == QLatin1Char('.');
    });
    if (!uid) return QStringLiteral("<b>%1</b><br>").arg(name.toHtmlEscaped());
    QString wrappable = name;
    wrappable.replace(QLatin1Char('.'), QStringLiteral(".\u200B"));
    return QStringLiteral("<b>%1</b><br><small>UID %2</small><br>")
        .arg(study.title().toHtmlEscaped(), wrappable);
}

} // namespace

void StudyPanel::showStudy(const StudyController& study) {
    const auto vol = study.volume();
    if (!vol) {
        m_info->setText(tr("No study"));
        return;
    }
    const auto spec = study.spectrum();
    const auto [lo, hi] = vol->valueRange();
    QString html = heading(study);
    if (const auto& s = study.series()) html += seriesLines(*s);
    html +=
        tr("Dimensions: %1 × %2 × %3<br>").arg(vol->dims[0]).arg(vol->dims[1]).arg(vol->dims[2]);
    html += tr("Spacing: %1 × %2 × %3 mm<br>")
                .arg(vol->spacing[0], 0, 'g', 4)
                .arg(vol->spacing[1], 0, 'g', 4)
                .arg(vol->spacing[2], 0, 'g', 4);
    html += tr("Values: %1 … %2 %3<br>")
                .arg(lo, 0, 'g', 5)
                .arg(hi, 0, 'g', 5)
                .arg(vol->units == core::ValueUnits::Unknown
                         ? tr("(units not stated)")
                         : QString::fromUtf8(core::unitsName(vol->units)));
    if (spec)
        html += tr("Spectrum: %1 × %2 × %3 padded, %4 MiB, %5<br>")
                    .arg(spec->padded[0])
                    .arg(spec->padded[1])
                    .arg(spec->padded[2])
                    .arg(double(spec->bytes()) / (1 << 20), 0, 'f', 1)
                    .arg(QString::fromUtf8(core::transformName(spec->kind)).toUpper());
    html +=
        tr("<small>Parallel projection without occlusion: every pixel is a line integral.</small>");
    for (const auto& w : study.warnings())
        html += QStringLiteral("<br><font color='#d04020'>⚠ %1</font>").arg(w.toHtmlEscaped());
    m_info->setText(html);
}

} // namespace fvr::ui
