"""Domain-free helpers of every aerostereo program: atomic file writes (:mod:`cliutil.atomic`), JSON reading that
names the file (:mod:`cliutil.jsonfile`), the bad-input error (:mod:`cliutil.errors`), argparse number types
(:mod:`cliutil.argtypes`), one-line errors and exit codes (:mod:`cliutil.program`), outputs that never name an
input (:mod:`cliutil.paths`), memory/disk checks before work starts (:mod:`cliutil.resources`) and progress on
stderr, tqdm bars or counted lines (:mod:`cliutil.progress`). It imports no aerostereo package."""
