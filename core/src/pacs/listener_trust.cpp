// The storage listener's trust: peers "AE[@host]", the listen address, hosts compared by address.
#include "listener_trust.h"

#include <fvr/core/pacs/pacs.h>

#include <algorithm>
#include <arpa/inet.h>
#include <netdb.h>
#include <sys/socket.h>

namespace fvr::core::pacs {
namespace detail {

std::vector<std::string> ipv4Addresses(const std::string& host) {
    std::vector<std::string> out;
    in_addr literal{};
    if (::inet_pton(AF_INET, host.c_str(), &literal) == 1) {
        char text[INET_ADDRSTRLEN];
        out.emplace_back(::inet_ntop(AF_INET, &literal, text, sizeof text));
        return out;
    }
    addrinfo hints{};
    hints.ai_family = AF_INET;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    if (host.empty() || ::getaddrinfo(host.c_str(), nullptr, &hints, &found) != 0) return out;
    for (const addrinfo* a = found; a; a = a->ai_next) {
        char text[INET_ADDRSTRLEN];
        const auto* sin = reinterpret_cast<const sockaddr_in*>(a->ai_addr);
        if (::inet_ntop(AF_INET, &sin->sin_addr, text, sizeof text) &&
            std::find(out.begin(), out.end(), text) == out.end())
            out.emplace_back(text);
    }
    ::freeaddrinfo(found);
    return out;
}

bool hostMatches(const std::string& host, const std::string& ip) {
    if (host.empty()) return true;
    const std::vector<std::string> ips = ipv4Addresses(host);
    return std::find(ips.begin(), ips.end(), ip) != ips.end();
}

std::string trimAe(std::string ae) {
    while (!ae.empty() && ae.back() == ' ') ae.pop_back();
    while (!ae.empty() && ae.front() == ' ') ae.erase(ae.begin());
    return ae;
}

} // namespace detail

namespace {

/** The rule of validate()'s AE titles: 1..16 characters, no backslash or control character, not
 *  all spaces. Empty when good, else why. */
std::string aeProblem(const std::string& ae) {
    if (ae.empty() || ae.size() > 16) return "must have 1 to 16 characters";
    if (detail::trimAe(ae).empty()) return "must not be all spaces";
    for (unsigned char c : ae)
        if (c < 0x20 || c == 0x7f || c == '\\')
            return "must not hold a backslash or a control character";
    return "";
}

} // namespace

Peer parsePeer(const std::string& text) {
    Peer peer;
    const auto at = text.find('@');
    peer.aeTitle = detail::trimAe(text.substr(0, at));
    if (at != std::string::npos) {
        peer.host = text.substr(at + 1);
        if (peer.host.empty())
            throw PacsError("allowed peer \"" + text + "\": no host after '@' (AE or AE@host)");
    }
    if (const std::string why = aeProblem(peer.aeTitle); !why.empty())
        throw PacsError("allowed peer \"" + text + "\": the AE title " + why + " (AE or AE@host)");
    return peer;
}

std::string describe(const Peer& peer) {
    return peer.host.empty() ? peer.aeTitle : peer.aeTitle + "@" + peer.host;
}

void validateListener(const LocalAe& local) {
    validate(local);
    in_addr addr{};
    if (!local.listenAddress.empty() &&
        ::inet_pton(AF_INET, local.listenAddress.c_str(), &addr) != 1)
        throw PacsError("the listen address \"" + local.listenAddress +
                        "\" is not an IPv4 address (127.0.0.1: this machine only; 0.0.0.0: "
                        "every interface)");
    for (const Peer& p : local.allowedPeers) {
        if (const std::string why = aeProblem(p.aeTitle); !why.empty())
            throw PacsError("allowed peer \"" + describe(p) + "\": the AE title " + why);
        if (!p.host.empty() && p.host.find_first_of(" \t\r\n") != std::string::npos)
            throw PacsError("allowed peer \"" + describe(p) + "\": the host holds a space");
    }
}

bool listensBeyondLoopback(const std::string& address) {
    in_addr addr{};
    if (::inet_pton(AF_INET, address.c_str(), &addr) != 1) return true; // "" = every interface
    return (ntohl(addr.s_addr) >> 24) != 127;
}

} // namespace fvr::core::pacs
