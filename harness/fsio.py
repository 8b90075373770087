"""File output shared by every harness script: a reader never sees a half
written file, even when the writer is interrupted or the disk fills."""
import os
import pathlib
import tempfile


def write_atomic(path, data):
    """Write text or bytes to `path` through a temp file in the same folder
    (same file system, so os.replace is atomic), with the umask's mode."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode() if isinstance(data, str) else data)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise
