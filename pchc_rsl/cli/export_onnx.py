"""pchc-export-onnx: export a checkpoint's policy to ONNX with inputs obs and preference."""

from __future__ import annotations

import os

from pchc_rsl.cli import arguments

PROG = "pchc-export-onnx"


def main(argv: list[str] | None = None) -> None:
    parser = arguments.Parser(
        prog=PROG,
        description="Export the deterministic policy of a pchc-train checkpoint to one self-contained ONNX file "
        "(inputs 'obs' [B, obs_dim] and 'preference' [B, m], output 'actions'; dynamic batch) and check it against "
        "torch in onnxruntime.",
    )
    parser.add_argument("checkpoint")
    parser.add_argument("-o", "--output", help="ONNX file (default: next to the checkpoint, same name .onnx)")
    parser.add_argument("--force", action="store_true", help="replace an existing --output file")
    parser.add_argument("-v", "--verbose", action="store_true", help="print torch's export messages and tracebacks")
    args = parser.parse_args(argv)
    from pchc_rsl.training.checkpoint_export import export_checkpoint  # torch: once the arguments are good

    output = args.output or os.path.splitext(args.checkpoint)[0] + ".onnx"
    if os.path.isdir(output):
        raise SystemExit(f"{PROG}: --output {output} is a folder; give a file name such as {output}/policy.onnx.")
    if os.path.exists(output) and not args.force:
        raise SystemExit(f"{PROG}: {output} exists; give another -o, or --force to replace it.")
    try:
        export_checkpoint(args.checkpoint, output, args.verbose)
    except (ValueError, FileNotFoundError, RuntimeError) as error:
        if args.verbose:
            raise
        raise SystemExit(f"{PROG}: {error}") from None
    print(f"{PROG}: wrote {output}")


if __name__ == "__main__":
    main()
