"""PNG output shared by the plot scripts: written to a temporary name and renamed, so a failed
plot never leaves a partial PNG under the final name (the C++ output layer's rule)."""
import os


def save_png(fig, path, dpi):
    tmp = "%s.tmp-%d" % (path, os.getpid())
    try:
        fig.savefig(tmp, dpi=dpi, format="png")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
