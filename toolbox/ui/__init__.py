"""The parameter layer shared by several algorithms: parameter presets, base algorithm classes,
and the one place where validated UPPERCASE parameters become the libraries' typed requests.

Only the framework (toolbox.algorithm, toolbox.parameters, runner, batch, registry, cli) and
``algorithms/`` import this package; the domain libraries never do (import-linter contract).
"""
