#pragma once
// The storage listener's trust (private to core): host names and addresses compared as IPv4
// addresses, the listening socket bound to one address.
#include <string>
#include <vector>

namespace fvr::core::pacs::detail {

/** The IPv4 addresses of `host` ("127.0.0.1" stays itself; a name is resolved); empty when it
 *  does not resolve. */
std::vector<std::string> ipv4Addresses(const std::string& host);

/** Whether a peer connecting from `ip` (numeric, as the listener sees it) is `host` (empty:
 *  any host; else one of its addresses). */
bool hostMatches(const std::string& host, const std::string& ip);

/** AE titles as they come in an association (padded with spaces) and as configured. */
std::string trimAe(std::string ae);

} // namespace fvr::core::pacs::detail
