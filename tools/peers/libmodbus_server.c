/* A libmodbus TCP server (select() over all clients, 1000 holding registers): the C
 * ceiling of the Modbus benchmark. Built at bench time by peers/libmodbus_peer.py:
 *     gcc -O2 libmodbus_server.c -o server $(pkg-config --cflags --libs libmodbus)
 *     ./server PORT      (0 = any free port; prints "listening PORT") */
#include <arpa/inet.h>
#include <errno.h>
#include <modbus.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

int main(int argc, char **argv) {
    int port = argc > 1 ? atoi(argv[1]) : 0;
    modbus_t *ctx = modbus_new_tcp("127.0.0.1", port);
    modbus_mapping_t *map = modbus_mapping_new(0, 0, 1000, 0);
    uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    if (ctx == NULL || map == NULL) return 1;
    int server = modbus_tcp_listen(ctx, 64);
    if (server < 0) { perror("listen"); return 1; }
    struct sockaddr_in addr;
    socklen_t len = sizeof addr;
    getsockname(server, (struct sockaddr *)&addr, &len);
    printf("listening %d\n", ntohs(addr.sin_port));
    fflush(stdout);
    fd_set all, ready;
    FD_ZERO(&all);
    FD_SET(server, &all);
    int fdmax = server;
    for (;;) {
        ready = all;
        if (select(fdmax + 1, &ready, NULL, NULL, NULL) < 0) {
            if (errno == EINTR) continue;
            return 1;
        }
        for (int fd = 0; fd <= fdmax; fd++) {
            if (!FD_ISSET(fd, &ready)) continue;
            if (fd == server) {
                int c = accept(server, NULL, NULL);
                if (c >= 0) {
                    FD_SET(c, &all);
                    if (c > fdmax) fdmax = c;
                }
                continue;
            }
            modbus_set_socket(ctx, fd);
            int rc = modbus_receive(ctx, query);
            if (rc > 0) {
                modbus_reply(ctx, query, rc, map);
            } else if (rc == -1) {
                close(fd);
                FD_CLR(fd, &all);
            }
        }
    }
}
