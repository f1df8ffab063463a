# SPDX-License-Identifier: Apache-2.0
# Sourced by the integration tests: a port for each daemon they start.
#
# free_udp_port: a UDP port on 127.0.0.1 that nothing is bound to, chosen by the kernel (a bind to
# port 0). ctest runs these scripts in parallel, and a random port from a fixed range collided with
# another test's daemon: the second daemon failed with "Address already in use", and its test went
# on talking to the other test's daemon.
free_udp_port() {
  python3 -c 'import socket
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1])'
}
