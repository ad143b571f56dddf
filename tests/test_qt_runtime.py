"""The Qt binding we install must survive long sessions: PySide6 6.12.0 under Python 3.11 drops a
reference to ``True`` on every signal emission and aborts the process after a few thousand
(a slider drag emits hundreds). Run in a subprocess so a regression fails this test, not the suite."""

import subprocess
import sys


# Needs no display (QCoreApplication, offscreen platform), so it runs headless too. PySide6 is a dependency:
# its absence is a failure, not a skip.

CODE = """
from PySide6.QtCore import QCoreApplication, QObject, Signal
app = QCoreApplication([])
class S(QObject):
    s = Signal(int, object)
got = []
o = S()
o.s.connect(lambda a, b: got.append(b))
for i in range(20000):
    o.s.emit(i, None)
print(len(got))
"""


def test_signals_survive_many_emissions():
    r = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=120,
                       env={"QT_QPA_PLATFORM": "offscreen", "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, f"Qt signal emission crashed the process: {r.stderr[-500:]}"
    assert r.stdout.strip() == "20000"
