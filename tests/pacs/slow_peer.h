#pragma once
// A peer that reaches a port and then sends as slowly as it can while staying within any
// per-byte timeout: the head of a PDU (or a TLS record) at once, then one byte a second.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <vector>

namespace fvr::test {

/** Connects to 127.0.0.1:`port`, sends `head`, then one byte (`filler`) a second until the
 *  other end closes the connection. Returns the seconds from the connection to that close, or
 *  -1 when it was still open after `guardSeconds` (or the connection failed). */
inline double dripUntilDropped(int port, const std::vector<unsigned char>& head,
                               unsigned char filler = 0x00, int guardSeconds = 30) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
        if (fd >= 0) ::close(fd);
        return -1;
    }
    const auto start = std::chrono::steady_clock::now();
    double droppedAfter = -1;
    bool sent = ::send(fd, head.data(), head.size(), MSG_NOSIGNAL) == ssize_t(head.size());
    for (int i = 0; i < guardSeconds && droppedAfter < 0; ++i) {
        pollfd p{fd, POLLIN, 0};
        char c;
        // Closed: a failed send, or end of file / a reset where a byte is awaited.
        if (!sent || (::poll(&p, 1, 1000) > 0 && ::recv(fd, &c, 1, MSG_DONTWAIT) <= 0))
            droppedAfter =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        else
            sent = ::send(fd, &filler, 1, MSG_NOSIGNAL) == 1;
    }
    ::close(fd);
    return droppedAfter;
}

} // namespace fvr::test
