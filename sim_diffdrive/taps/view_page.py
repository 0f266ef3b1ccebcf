# Copyright 2026 motion_challenges contributors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
The browser view's page: Rerun's web viewer, confined to this machine (no ROS imports).

``ViewerPage`` serves the rerun program's viewer files on ``view_port`` under a CSP that lets
the page talk to this machine only: Rerun's page would otherwise fetch a web font, release and
example lists, and send analytics (its web build has no switch for that).  Requests whose Host
is not this machine's are refused (DNS rebinding).
"""

import contextlib
import http.client
from http.server import BaseHTTPRequestHandler
from http.server import ThreadingHTTPServer
import random
import re
import socket
import threading

# What the page may load and talk to: itself, and the gRPC port the viewer streams from.
# wasm-unsafe-eval compiles the viewer's WebAssembly; inline script and style are index.html's.
CSP = ("default-src 'self'; script-src 'self' 'unsafe-inline' 'wasm-unsafe-eval'; "
       "style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; font-src 'self' data:; "
       "worker-src 'self' blob:; connect-src 'self' {grpc}; form-action 'none'; "
       "base-uri 'none'; frame-ancestors 'none'")
_FONT_LINK = re.compile(rb'<link\b[^>]*fonts\.(?:googleapis|gstatic)\.com[^>]*>')
_CHUNK = 1 << 20
# The page asks the port which run it serves (id, gRPC address) once a second and opens a new
# one at once: a simulator started again on the same view_port shows without a reload.
RUN_PATH = '/run'
_FOLLOW = (f"<script>setInterval(() => fetch('{RUN_PATH}').then(r => r.text()).then(run => {{"
           " const [id, url] = run.split(' '); if (id && url && id !== 'RUN')"
           " location.replace('/?url=' + encodeURIComponent(url)); }).catch(() => {}), 1000);"
           '</script>')
_LOCAL_HOSTS = ('127.0.0.1', 'localhost')
# Headers of the upstream answer passed on (rerun-final-length drives the page's progress bar).
_PASSED_HEADERS = ('content-type', 'rerun-final-length', 'content-encoding')


def ephemeral_ports():
    """Return the range the kernel takes the local ports of outgoing connections from."""
    with contextlib.suppress(OSError, ValueError):
        with open('/proc/sys/net/ipv4/ip_local_port_range') as ports:
            low, high = map(int, ports.read().split())
            return range(low, high + 1)
    return range(32768, 61000)  # Linux's default


def free_port(host='127.0.0.1'):
    """
    Return a TCP port free on host now, below the ephemeral range where one can be found.

    The port is handed to a server that binds it later.  Any outgoing connection on the
    machine (the page's own requests to the rerun program, a test's client) may take a
    free ephemeral port meanwhile, so a port from that range is a race.
    """
    below = range(10000, ephemeral_ports().start)  # above the ports services are known on
    for port in random.sample(below, min(64, len(below))):
        if port_is_free(host, port):
            return port
    with socket.socket() as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]


def port_is_free(host, port):
    """Return whether a server could bind host:port now."""
    with socket.socket() as probe:
        # As the servers bind: connections in TIME_WAIT do not keep the port.
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError:
            return False
    return True


def page_url(port, grpc_url):
    """Return the address to open: the viewer on port, told to stream from grpc_url."""
    from urllib.parse import quote
    return f'http://127.0.0.1:{port}/?url={quote(grpc_url, safe="")}'


def confine(html):
    """Return index.html without the links to Google's web font (the page's other styles stay)."""
    return _FONT_LINK.sub(b'', html)


def follow(html, run):
    """Return index.html that opens the next run to serve this port (see RUN_PATH)."""
    script = _FOLLOW.replace('RUN', run).encode()
    return html.replace(b'</body>', script + b'</body>', 1)


class ViewerPage:
    """Serve the viewer's files from the rerun program on upstream_port, on host:port."""

    def __init__(self, host, port, upstream_port, grpc_origins, run):
        """
        Listen on host:port now (OSError when the port is taken) and serve from a thread.

        grpc_origins: the origins the page may stream from; run: (id, gRPC url) of this run.
        """
        self._server = ThreadingHTTPServer((host, port), _PageHandler)
        self._server.daemon_threads = True
        # What the handler (one per request) reads from its server.
        self._server.upstream_port, self._server.run = upstream_port, run
        self._server.csp = CSP.format(grpc=' '.join(grpc_origins))
        self.port = self._server.server_address[1]
        self._thread = threading.Thread(
            target=self._server.serve_forever, kwargs={'poll_interval': 0.2},
            name=f'view_page:{self.port}', daemon=True)
        self._thread.start()

    def close(self):
        """Stop serving and free the port (idempotent)."""
        server, self._server = self._server, None
        if server is not None:
            server.shutdown()
            server.server_close()
            self._thread.join(timeout=5.0)


class _PageHandler(BaseHTTPRequestHandler):
    """GET: the upstream file, under the policy; index.html without the font links."""

    def do_GET(self):  # noqa: N802 (the name http.server dispatches to)
        port, run = self.server.server_address[1], self.server.run
        if self.headers.get('Host') not in {f'{host}:{port}' for host in _LOCAL_HOSTS}:
            self.send_error(403, 'this viewer answers to 127.0.0.1 and localhost only')
            return
        path, _, query = self.path.partition('?')
        if path == RUN_PATH:
            self._send(200, [('Content-Type', 'text/plain'), ('Cache-Control', 'no-store')],
                       ' '.join(run).encode())
            return
        if path == '/' and 'url=' not in query:  # http://127.0.0.1:PORT/ opens this run
            self._send(302, [('Location', page_url(port, run[1]))], b'')
            return
        upstream = http.client.HTTPConnection('127.0.0.1', self.server.upstream_port, timeout=10.0)
        try:
            try:
                upstream.request('GET', path)
                answer = upstream.getresponse()
            except OSError as error:
                self.send_error(502, f'the rerun program did not answer: {error}')
                return
            headers = [(name, answer.getheader(name)) for name in _PASSED_HEADERS
                       if answer.getheader(name) is not None] + [('Cache-Control', 'no-cache')]
            if path in ('/', '/index.html') and answer.status == 200:
                self._send(200, headers, follow(confine(answer.read()), run[0]))
            else:
                self._send(answer.status, headers, stream=answer)
        except (ConnectionError, TimeoutError):
            pass  # the browser left (a tab closed mid-download) or the upstream stalled
        finally:
            upstream.close()

    def _send(self, status, headers, body=None, stream=None):
        self.send_response(status)
        for name, value in headers:
            self.send_header(name, value)
        if body is not None:
            self.send_header('Content-Length', str(len(body)))
        self.send_header('Content-Security-Policy', self.server.csp)
        self.end_headers()
        if body is not None:
            self.wfile.write(body)
        # HTTP/1.0: the body ends when the connection closes, so it can stream as it comes.
        while stream is not None and (chunk := stream.read(_CHUNK)):
            self.wfile.write(chunk)

    def log_message(self, format, *args):  # noqa: A002 (http.server's signature)
        pass  # a page load is not news; failures reach the browser
