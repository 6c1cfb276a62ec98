// A bare UDP socket on 127.0.0.1 for tests that play one side of the RDT
// protocol by hand: independently written packing, so the production codec
// is checked against something it does not share code with.
#ifndef BITEWISE_TESTS_ROBOT_UDP_TEST_PEER_H_
#define BITEWISE_TESTS_ROBOT_UDP_TEST_PEER_H_

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <vector>

namespace bitewise::testing {

class UdpTestPeer {
 public:
  UdpTestPeer() {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
    socklen_t len = sizeof(addr);
    getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
    int buffer_bytes = 1 << 20;
    setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &buffer_bytes, sizeof(buffer_bytes));
  }
  ~UdpTestPeer() { close(fd_); }
  UdpTestPeer(const UdpTestPeer&) = delete;
  UdpTestPeer& operator=(const UdpTestPeer&) = delete;

  uint16_t port() const { return port_; }

  // Waits up to `timeout` for one datagram; remembers its sender as the
  // peer for SendTo().
  std::optional<std::vector<uint8_t>> Receive(
      std::chrono::milliseconds timeout) {
    pollfd pfd{fd_, POLLIN, 0};
    if (poll(&pfd, 1, static_cast<int>(timeout.count())) <= 0) {
      return std::nullopt;
    }
    std::vector<uint8_t> buffer(2048);
    socklen_t len = sizeof(peer_);
    const ssize_t n = recvfrom(fd_, buffer.data(), buffer.size(), 0,
                               reinterpret_cast<sockaddr*>(&peer_), &len);
    if (n < 0) return std::nullopt;
    have_peer_ = true;
    buffer.resize(static_cast<size_t>(n));
    return buffer;
  }

  bool SendToPeer(const std::vector<uint8_t>& bytes) {
    if (!have_peer_) return false;
    return sendto(fd_, bytes.data(), bytes.size(), 0,
                  reinterpret_cast<const sockaddr*>(&peer_),
                  sizeof(peer_)) == static_cast<ssize_t>(bytes.size());
  }

  bool SendToPort(uint16_t port, const std::vector<uint8_t>& bytes) {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    to.sin_port = htons(port);
    return sendto(fd_, bytes.data(), bytes.size(), 0,
                  reinterpret_cast<const sockaddr*>(&to),
                  sizeof(to)) == static_cast<ssize_t>(bytes.size());
  }

 private:
  int fd_ = -1;
  uint16_t port_ = 0;
  sockaddr_in peer_{};
  bool have_peer_ = false;
};

// Big-endian by hand, for packets the tests write themselves.
inline void AppendBigEndian32(uint32_t value, std::vector<uint8_t>* out) {
  out->push_back(static_cast<uint8_t>((value >> 24) & 0xff));
  out->push_back(static_cast<uint8_t>((value >> 16) & 0xff));
  out->push_back(static_cast<uint8_t>((value >> 8) & 0xff));
  out->push_back(static_cast<uint8_t>(value & 0xff));
}

inline uint32_t ReadBigEndian32(const std::vector<uint8_t>& in, size_t at) {
  return (static_cast<uint32_t>(in[at]) << 24) |
         (static_cast<uint32_t>(in[at + 1]) << 16) |
         (static_cast<uint32_t>(in[at + 2]) << 8) |
         static_cast<uint32_t>(in[at + 3]);
}

// A 36-byte RDT record written field by field.
inline std::vector<uint8_t> HandWrittenRecord(
    uint32_t rdt_sequence, uint32_t ft_sequence, uint32_t status,
    const std::array<int32_t, 6>& counts) {
  std::vector<uint8_t> out;
  AppendBigEndian32(rdt_sequence, &out);
  AppendBigEndian32(ft_sequence, &out);
  AppendBigEndian32(status, &out);
  for (int32_t c : counts) AppendBigEndian32(static_cast<uint32_t>(c), &out);
  return out;
}

}  // namespace bitewise::testing

#endif  // BITEWISE_TESTS_ROBOT_UDP_TEST_PEER_H_
