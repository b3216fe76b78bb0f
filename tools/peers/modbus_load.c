/* A C Modbus TCP load generator: CLIENTS closed-loop connections multiplexed with poll()
 * in one process, each sending one pre-built request and waiting for the whole reply,
 * again and again, for SECONDS. Light enough that the server, not the generator, is what
 * saturates on a 2-core machine. Built at bench time by tools/bench_modbus_c.py:
 *     gcc -O2 modbus_load.c -o load
 *     ./load PORT CLIENTS SECONDS FC QTY ADDR
 * FC 3 reads QTY registers at ADDR, FC 16 writes QTY registers there. Prints one line:
 *     replies N errors E seconds S */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define MAXC 64

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

int main(int argc, char **argv) {
    if (argc != 7) {
        fprintf(stderr, "usage: load PORT CLIENTS SECONDS FC QTY ADDR\n");
        return 2;
    }
    int port = atoi(argv[1]), n = atoi(argv[2]), fc = atoi(argv[4]), qty = atoi(argv[5]);
    int addr = atoi(argv[6]);
    double seconds = atof(argv[3]);
    if (n < 1 || n > MAXC || (fc != 3 && fc != 16) || qty < 1 || qty > 123) return 2;
    unsigned char req[260];
    int len, reply;
    req[0] = 0; req[1] = 1; req[2] = 0; req[3] = 0; req[6] = 1; req[7] = (unsigned char)fc;
    req[8] = addr >> 8; req[9] = addr & 0xFF; req[10] = qty >> 8; req[11] = qty & 0xFF;
    if (fc == 3) {
        len = 12;
        reply = 9 + 2 * qty;
    } else {
        req[12] = (unsigned char)(2 * qty);
        for (int i = 0; i < 2 * qty; i++) req[13 + i] = (unsigned char)i;
        len = 13 + 2 * qty;
        reply = 12;
    }
    req[4] = (len - 6) >> 8; req[5] = (len - 6) & 0xFF;
    struct pollfd fds[MAXC];
    int got[MAXC];
    struct sockaddr_in sa;
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    sa.sin_port = htons(port);
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    for (int i = 0; i < n; i++) {
        int s = socket(AF_INET, SOCK_STREAM, 0), one = 1;
        if (s < 0 || connect(s, (struct sockaddr *)&sa, sizeof sa) < 0) {
            perror("connect");
            return 1;
        }
        setsockopt(s, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        fds[i].fd = s;
        fds[i].events = POLLIN;
        got[i] = 0;
    }
    long replies = 0, errors = 0;
    unsigned char buf[512];
    double t0 = now(), end = t0 + seconds;
    for (int i = 0; i < n; i++)
        if (send(fds[i].fd, req, len, 0) != len) return 1;
    int active = n;
    while (active) {
        int r = poll(fds, n, 5000);
        if (r <= 0) { errors++; break; }  /* a server that stopped answering */
        for (int i = 0; i < n; i++) {
            if (!(fds[i].revents & (POLLIN | POLLERR | POLLHUP))) continue;
            ssize_t k = recv(fds[i].fd, buf, sizeof buf, 0);
            if (k <= 0) { errors++; close(fds[i].fd); fds[i].fd = -1; active--; continue; }
            got[i] += (int)k;
            if (got[i] >= 9 && (buf[7] & 0x80)) { errors++; got[i] = reply; }
            if (got[i] < reply) continue;
            got[i] = 0;
            replies++;
            if (now() >= end) { close(fds[i].fd); fds[i].fd = -1; active--; continue; }
            if (send(fds[i].fd, req, len, 0) != len) { errors++; fds[i].fd = -1; active--; }
        }
    }
    printf("replies %ld errors %ld seconds %.6f\n", replies, errors, now() - t0);
    return 0;
}
