// C-ECHO, C-FIND, C-GET, C-MOVE and C-STORE as a service class user (DCMTK's DcmSCU).
#include <fvr/core/pacs/dicom_url.h>
#include <fvr/core/pacs/local_store.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/pacs/storage_listener.h>

#include <algorithm>

namespace fvr::core::pacs {
namespace {

void validateAe(const std::string& ae, const std::string& what) {
    if (ae.empty() || ae.size() > 16)
        throw PacsError(what + " \"" + ae + "\" must have 1 to 16 characters");
    if (std::all_of(ae.begin(), ae.end(), [](char c) { return c == ' '; }))
        throw PacsError(what + " must not be all spaces");
    for (char c : ae)
        if (c == '\\' || static_cast<unsigned char>(c) < 0x20 ||
            static_cast<unsigned char>(c) > 0x7e)
            throw PacsError(what + " \"" + ae +
                            "\" may hold only printable ASCII characters other than '\\'");
}

void validatePort(int port, const std::string& what) {
    if (port < 1 || port > 65535)
        throw PacsError(what + " " + std::to_string(port) + " is not in 1..65535");
}

} // namespace

std::string describe(const Node& node) {
    return node.calledAe + "@" + node.host + ":" + std::to_string(node.port);
}

void validate(const Node& node) {
    validateAe(node.calledAe, "the called AE title");
    if (node.host.empty()) throw PacsError("the PACS host is empty");
    validatePort(node.port, "the PACS port");
}

void validate(const LocalAe& local) {
    validateAe(local.aeTitle, "our AE title");
    validatePort(local.listenPort, "our listener port");
    if (local.timeoutSeconds < 1) throw PacsError("the network timeout must be at least 1 s");
}

} // namespace fvr::core::pacs
