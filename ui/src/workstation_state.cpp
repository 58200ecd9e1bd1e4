// The workstation's state as data (undo/redo, sessions) and its INI form.
#include <fvr/ui/workstation_state.h>

#include <QObject>
#include <QSettings>
#include <QStringList>

#include <algorithm>
#include <cmath>

#include <fvr/core/errors.h>
#include <fvr/ui/panels/geometry_panel.h>
#include <fvr/ui/study.h>

namespace fvr::ui {

namespace {

bool near(double a, double b, double rel = 1e-9) {
    return std::abs(a - b) <= rel * std::max({1.0, std::abs(a), std::abs(b)});
}

bool sameVec(const core::Vec3& a, const core::Vec3& b) {
    return near(a.x, b.x) && near(a.y, b.y) && near(a.z, b.z);
}

bool sameFrame(const core::ViewFrame& a, const core::ViewFrame& b) {
    return sameVec(a.d, b.d) && sameVec(a.u, b.u) && sameVec(a.r, b.r);
}

bool sameView(const ViewState& a, const ViewState& b) {
    return near(a.window.low, b.window.low) && near(a.window.high, b.window.high) &&
           a.window.invert == b.window.invert && near(a.zoom, b.zoom) &&
           near(a.pan.x(), b.pan.x()) && near(a.pan.y(), b.pan.y());
}

QString vecText(const core::Vec3& v) {
    return QStringLiteral("%1 %2 %3")
        .arg(v.x, 0, 'g', 17)
        .arg(v.y, 0, 'g', 17)
        .arg(v.z, 0, 'g', 17);
}

bool parseVec(const QString& text, core::Vec3* out) {
    const QStringList parts = text.split(' ', Qt::SkipEmptyParts);
    if (parts.size() != 3) return false;
    bool ok[3];
    const core::Vec3 v{parts[0].toDouble(&ok[0]), parts[1].toDouble(&ok[1]),
                       parts[2].toDouble(&ok[2])};
    if (!(ok[0] && ok[1] && ok[2]) || !std::isfinite(v.x + v.y + v.z)) return false;
    *out = v;
    return true;
}

core::ViewFrame loadFrame(const QSettings& s, const core::ViewFrame& base) {
    core::Vec3 d, u;
    if (!parseVec(s.value("workstation/direction").toString(), &d) ||
        !parseVec(s.value("workstation/up").toString(), &u))
        return base;
    try {
        return core::ViewFrame::fromDirUp(d, u);
    } catch (const core::SettingsError&) {
        return base; // a zero direction or an up along it: the default
    }
}

void saveSlot(QSettings& s, const ViewSettings& v) {
    RenderingPanel::Values r;
    r.kernel = v.kernel;
    r.size = v.size;
    r.voxelModel = v.voxelModel;
    RenderingPanel::save(s, r);
    GeometryPanel::save(s, {v.projection, v.cone});
}

ViewSettings loadSlot(const QSettings& s, ViewSettings base) {
    RenderingPanel::Values r;
    r.kernel = base.kernel;
    r.size = base.size;
    r.voxelModel = base.voxelModel;
    r = RenderingPanel::load(s, r);
    base.kernel = r.kernel;
    base.size = r.size;
    base.voxelModel = r.voxelModel;
    if (s.contains("geometry/projection")) {
        const GeometryPanel::Values g = GeometryPanel::load(s);
        base.projection = g.projection;
        base.cone = g.cone;
    }
    return base;
}

} // namespace

bool WorkstationState::sameAs(const WorkstationState& o) const {
    if (compareCount != o.compareCount || difference != o.difference ||
        compareSlots != o.compareSlots || !(rendering == o.rendering) || !(xray == o.xray) ||
        !sameFrame(frame, o.frame) || views.size() != o.views.size())
        return false;
    for (std::size_t i = 0; i < views.size(); ++i)
        if (!sameView(views[i], o.views[i])) return false;
    return true;
}

QString WorkstationState::changeFrom(const WorkstationState& b) const {
    if (compareCount != b.compareCount) return QObject::tr("Compare views");
    if (difference != b.difference) return QObject::tr("Difference");
    if (!(xray == b.xray)) return QObject::tr("X-ray setting");
    if (!(rendering == b.rendering) || compareSlots != b.compareSlots)
        return QObject::tr("Render setting");
    if (!sameFrame(frame, b.frame)) return QObject::tr("Rotation");
    for (std::size_t i = 0; i < std::min(views.size(), b.views.size()); ++i) {
        if (!near(views[i].zoom, b.views[i].zoom) || views[i].pan != b.views[i].pan)
            return QObject::tr("Zoom");
    }
    return QObject::tr("Window");
}

void saveState(QSettings& s, const WorkstationState& st) {
    s.setValue("workstation/compareCount", st.compareCount);
    s.setValue("workstation/difference", st.difference);
    s.setValue("workstation/direction", vecText(st.frame.d));
    s.setValue("workstation/up", vecText(st.frame.u));
    RenderingPanel::save(s, st.rendering);
    XrayPanel::save(s, st.xray);
    for (std::size_t i = 0; i < st.compareSlots.size(); ++i) {
        s.beginGroup(QStringLiteral("view%1").arg(i + 1));
        saveSlot(s, st.compareSlots[i]);
        if (i < st.views.size()) {
            const ViewState& v = st.views[i];
            s.setValue("window/low", v.window.low);
            s.setValue("window/high", v.window.high);
            s.setValue("window/invert", v.window.invert);
            s.setValue("zoom", v.zoom);
            s.setValue("pan", QStringLiteral("%1 %2").arg(v.pan.x()).arg(v.pan.y()));
        }
        s.endGroup();
    }
}

WorkstationState loadState(QSettings& s, WorkstationState st) {
    const int n = s.value("workstation/compareCount", st.compareCount).toInt();
    st.compareCount = n >= 4 ? 4 : (n >= 2 ? 2 : 1);
    st.difference = s.value("workstation/difference", st.difference).toBool() && n > 1;
    st.frame = loadFrame(s, st.frame);
    st.rendering = RenderingPanel::load(s, st.rendering);
    st.xray = XrayPanel::load(s, st.xray);
    st.views.resize(std::size_t(st.compareCount));
    for (std::size_t i = 0; i < st.compareSlots.size(); ++i) {
        const QString g = QStringLiteral("view%1/").arg(i + 1);
        s.beginGroup(g.chopped(1));
        st.compareSlots[i] = loadSlot(s, st.compareSlots[i]);
        s.endGroup();
        if (i >= st.views.size()) continue;
        ViewState& v = st.views[i];
        const double lo = s.value(g + "window/low", v.window.low).toDouble();
        const double hi = s.value(g + "window/high", v.window.high).toDouble();
        if (std::isfinite(lo) && std::isfinite(hi) && hi > lo) {
            v.window.low = lo;
            v.window.high = hi;
        }
        v.window.invert = s.value(g + "window/invert", false).toBool();
        const double z = s.value(g + "zoom", v.zoom).toDouble();
        if (std::isfinite(z) && z > 0) v.zoom = z;
        const QStringList pan = s.value(g + "pan").toString().split(' ', Qt::SkipEmptyParts);
        if (pan.size() == 2) v.pan = {pan[0].toDouble(), pan[1].toDouble()};
    }
    return st;
}

void saveStudySource(QSettings& s, const StudySource& src) {
    if (src.kind == StudySource::Kind::Phantom) {
        s.setValue("study/source",
                   QStringLiteral("phantom:%1:%2")
                       .arg(src.phantomKind == core::PhantomKind::Chest ? "chest" : "shepp-logan")
                       .arg(src.phantomSize));
    } else {
        s.setValue("study/source", src.path);
    }
    if (!src.seriesKey.isEmpty()) s.setValue("study/series", src.seriesKey);
}

StudySource loadStudySource(const QSettings& s) {
    const QString source = s.value("study/source").toString();
    if (source.isEmpty())
        throw core::SettingsError("the session names no study (study/source is missing)");
    StudySource src = StudySource::fromPath(source);
    src.seriesKey = s.value("study/series").toString();
    return src;
}

} // namespace fvr::ui
