function [P, variant] = thesis_problem(args, driver, variants)
% THESIS_PROBLEM  Read a driver's command line {problem} {trajectory} [variant]
% and the problem file (protocol version 1 of rk4core/command.py).
%   P.trajectory is the output path; VARIANT is one of VARIANTS (default: the
%   first). Errors name the driver.
  if numel(args) < 2 || numel(args) > 3
    error('%s: usage: octave-cli %s.m PROBLEM.json TRAJECTORY.csv [%s]', driver, driver, ...
          strjoin(variants, '|'));
  end
  variant = variants{1};
  if numel(args) == 3
    variant = args{3};
  end
  if ~any(strcmp(variant, variants))
    error('%s: variant must be one of %s, got "%s"', driver, strjoin(variants, ', '), variant);
  end
  P = jsondecode(fileread(args{1}));
  if ~isfield(P, 'protocol') || P.protocol ~= 1
    error('%s: %s is not a protocol 1 problem', driver, args{1});
  end
  P.y0 = P.y0(:);
  P.trajectory = args{2};
end
