"""Matplotlib for the figures of every stage: the off-screen backend, and a figure saved
as PDF with a PNG beside it (150 dpi) for viewers that do not open PDF."""

from pathlib import Path


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (no screen needed), imported on first use."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, out_pdf, out_png=None) -> None:
    """``fig`` written to ``out_pdf`` and to ``out_png`` (default: the PDF's name as .png),
    then closed."""
    out_pdf = Path(out_pdf)
    out_pdf.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_pdf)
    fig.savefig(out_png or out_pdf.with_suffix(".png"), dpi=150)
    pyplot().close(fig)
