# SPDX-License-Identifier: GPL-2.0-or-later
"""A recipe reaches no network, whatever the files it names contain: a local
HTTP server counts the requests while GDAL reads recipes whose inputs lead
to it (a VRT naming /vsicurl/, VRTs nested, a WMS or WMTS description named
.tif, a VRT over a WMS file, an inline WMS source, a database connection),
through gdal_translate and the Dask runner.  The oracle is the server's own
count: zero requests, unless TSYN_ALLOW_NETWORK=YES (then the same recipe
reaches it: the test can fail).  Standard input, FIFOs and devices are
refused as inputs."""
import http.server
import os
import shutil
import subprocess
import sys
import threading

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
PLUGINS = os.environ.get("TS_GDAL_PLUGINS", os.path.join(ROOT, "build", "gdalplugins"))
DATA = os.environ.get("TS_DATA_DIR", os.path.join(ROOT, "data"))
DEM = os.path.join(DATA, "jacksboro_fault_dem.tif")
DASK = os.path.join(ROOT, "gdal_driver", "dask", "terrasynth_dask.py")
ENV = dict(os.environ, GDAL_DRIVER_PATH=PLUGINS)
for k in ("TSYN_ALLOW_NETWORK", "NO_PROXY", "no_proxy", "http_proxy", "HTTP_PROXY"):
    ENV.pop(k, None)


class Counter(http.server.SimpleHTTPRequestHandler):
    hits = []

    def log_message(self, *args):
        pass

    def do_GET(self):
        Counter.hits.append(self.path)
        super().do_GET()

    def do_HEAD(self):
        Counter.hits.append(self.path)
        super().do_HEAD()


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    root = tmp_path_factory.mktemp("served")
    shutil.copy(DEM, root / "secret.tif")

    def handler(*a, **kw):
        return Counter(*a, directory=str(root), **kw)

    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    yield "http://127.0.0.1:%d" % srv.server_address[1]
    srv.shutdown()


def vrt_over(name, relative=False):
    return ('<VRTDataset rasterXSize="100" rasterYSize="100"><SRS>EPSG:32616</SRS>'
            '<GeoTransform>700000, 90, 0, 4000000, 0, -90</GeoTransform>'
            '<VRTRasterBand dataType="Float32" band="1"><SimpleSource>'
            '<SourceFilename relativeToVRT="%d">%s</SourceFilename><SourceBand>1</SourceBand>'
            '</SimpleSource></VRTRasterBand></VRTDataset>' % (int(relative), name))


def wms(url):
    return ('<GDAL_WMS><Service name="TMS"><ServerUrl>%s/tiles/${z}/${x}/${y}.png</ServerUrl>'
            '</Service><DataWindow><UpperLeftX>-20037508.34</UpperLeftX><UpperLeftY>20037508.34'
            '</UpperLeftY><LowerRightX>20037508.34</LowerRightX><LowerRightY>-20037508.34'
            '</LowerRightY><TileLevel>0</TileLevel><TileCountX>1</TileCountX><TileCountY>1'
            '</TileCountY><YOrigin>top</YOrigin></DataWindow><Projection>EPSG:3857</Projection>'
            '<BlockSizeX>256</BlockSizeX><BlockSizeY>256</BlockSizeY><BandsCount>1</BandsCount>'
            '</GDAL_WMS>' % url)


def recipe(path, exemplar):
    path.write_text("<TerraSynth version='1'><Synth><Exemplar>%s</Exemplar>"
                    "<Grid width='64' height='64'/></Synth></TerraSynth>" % exemplar)


def inputs(d, url):
    """name -> what the recipe's exemplar is (files written into d)."""
    (d / "remote.vrt").write_text(vrt_over("/vsicurl/%s/secret.tif" % url))
    (d / "nested.vrt").write_text(vrt_over("remote.vrt", relative=True))
    (d / "wms.tif").write_text(wms(url))
    (d / "wmts.tif").write_text("<GDAL_WMTS><GetCapabilitiesUrl>%s/wmts.xml"
                                "</GetCapabilitiesUrl></GDAL_WMTS>" % url)
    (d / "over_wms.vrt").write_text(vrt_over("wms.tif", relative=True))
    (d / "inline.vrt").write_text(vrt_over(wms(url).replace("<", "&lt;").replace(">", "&gt;")))
    (d / "zip.vrt").write_text(vrt_over("/vsizip//vsicurl/%s/a.zip/x.tif" % url))
    return {"vrt_vsicurl": "remote.vrt", "vrt_nested": "nested.vrt", "wms": "wms.tif",
            "wmts": "wmts.tif", "vrt_over_wms": "over_wms.vrt", "vrt_inline_wms": "inline.vrt",
            "vrt_vsizip_vsicurl": "zip.vrt", "postgres": "PG:host=127.0.0.1 dbname=x"}


CASES = ["vrt_vsicurl", "vrt_nested", "wms", "wmts", "vrt_over_wms", "vrt_inline_wms",
         "vrt_vsizip_vsicurl", "postgres"]


@pytest.mark.parametrize("case", CASES)
def test_no_request_through_gdal_translate(server, tmp_path, case):
    name = inputs(tmp_path, server)[case]
    recipe(tmp_path / "r.tsyn", name)
    Counter.hits.clear()
    p = subprocess.run(["gdal_translate", "-q", "r.tsyn", "o.tif"], cwd=tmp_path, env=ENV,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode != 0
    assert Counter.hits == []
    assert "TSYN_ALLOW_NETWORK" in p.stderr or "reads files only" in p.stderr, p.stderr
    assert not (tmp_path / "o.tif").exists()


def test_allowed_network_reaches_the_server(server, tmp_path):
    """The oracle can fail: with the option set, the same recipe is served
    from the server."""
    recipe(tmp_path / "r.tsyn", inputs(tmp_path, server)["vrt_vsicurl"])
    Counter.hits.clear()
    p = subprocess.run(["gdal_translate", "-q", "r.tsyn", "o.tif"], cwd=tmp_path,
                       env=dict(ENV, TSYN_ALLOW_NETWORK="YES"), capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    assert any("secret.tif" in h for h in Counter.hits)


def test_local_vrt_still_read(tmp_path):
    """A VRT over a local file is read as before (no false refusal)."""
    shutil.copy(DEM, tmp_path / "dem.tif")
    (tmp_path / "local.vrt").write_text(vrt_over("dem.tif", relative=True))
    recipe(tmp_path / "r.tsyn", "local.vrt")
    p = subprocess.run(["gdal_translate", "-q", "r.tsyn", "o.tif"], cwd=tmp_path, env=ENV,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr


def test_no_request_through_the_dask_runner(server, tmp_path):
    pytest.importorskip("distributed")
    recipe(tmp_path / "r.tsyn", inputs(tmp_path, server)["vrt_nested"])
    Counter.hits.clear()
    p = subprocess.run(["/usr/bin/python3", DASK, "r.tsyn", "o.tif", "--workers", "1", "-q"],
                       cwd=tmp_path, env=ENV, capture_output=True, text=True, timeout=300)
    assert p.returncode != 0
    assert Counter.hits == []
    assert not (tmp_path / "o.tif").exists()


@pytest.mark.parametrize("name", ["/vsistdin/", "/vsisubfile/0_100,/vsistdin/", "fifo.tif",
                                  "/dev/zero"])
def test_no_stdin_fifo_or_device(tmp_path, name):
    os.mkfifo(tmp_path / "fifo.tif")
    recipe(tmp_path / "r.tsyn", name)
    r, w = os.pipe()  # a standard input that stays open: a read of it would block
    try:
        p = subprocess.run(["gdalinfo", "r.tsyn"], cwd=tmp_path, env=ENV, stdin=r,
                           capture_output=True, text=True, timeout=30)
    finally:
        os.close(r)
        os.close(w)
    assert p.returncode != 0
    assert "standard input" in p.stderr or "not a regular file" in p.stderr, p.stderr
