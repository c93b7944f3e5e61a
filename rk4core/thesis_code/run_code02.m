% RUN_CODE02  Run the semi-implicit Euler loop of Code 02 (code02.m) on a
% protocol problem.
%
%   octave-cli --no-history --norc --quiet run_code02.m PROBLEM.json TRAJECTORY.csv [printed|corrected]
%
% The problem must be linear with the stiffness matrix of n equal masses m
% joined by equal springs k between two walls (the matrix Code 02 builds;
% checked after the printed code has built it). Runs code02.m from
% "% Assume spring constants ..." to the end of the loop as printed, with these lines replaced:
%   m = input(...) / k = input(...) / n = input(...) -> the problem's m, k, n
%   t = input('Simulation time period: \n');  -> t = t_end - t0 (printed)
%                                                t = t_end - t0 + h (corrected)
%   tStep=0.001;                              -> tStep = problem h
%   x(1,:)=phi(:,mode);                       -> x(1,:), v(1,:) = y0
% and one line added after "iterations=t/tStep;": iterations =
% round(iterations) (t/tStep is an integer up to round-off).
% "printed" keeps tVector=tStep.*(1:iterations): its rows are the states
% after 0 .. n_steps-1 steps, labelled t0 + h .. t0 + n_steps h (one step
% late). "corrected" runs one more row (the state after n_steps steps) and
% labels row i with t0 + (i-1) h (tVector=tStep.*(0:iterations-1)).
% Writes t0 + tVector, x, v and stats.json (nfev = one evaluation of the
% accelerations per step).
% Any error ends the run with one line "error: ..." on stderr and exit status 1.
try
  addpath(fileparts(mfilename('fullpath')));
  [drv_P, drv_variant] = thesis_problem(argv(), 'run_code02', {'printed', 'corrected'});
  [drv_m, drv_k] = thesis_chain_springs(drv_P, 'run_code02');
  if any(drv_m ~= drv_m(1)) || any(abs(drv_k - drv_k(1)) > 1e-14 * drv_k(1))
    error('run_code02: Code 02 integrates equal masses joined by equal springs between two walls; the problem has masses [%s] and springs [%s]', num2str(drv_m), num2str(drv_k));
  end
  drv_T = drv_P.t_end - drv_P.t0;
  if strcmp(drv_variant, 'corrected')
    drv_T = drv_T + drv_P.h;
  end
  drv_edits = {
    'm = input(''Enter value of Mass Weight (kg): \n'');', '', 'm = drv_m(1);'
    'k = input(''Enter value of the spring constants (N/m): \n'');', '', 'k = drv_k(1);'
    'n = input(''Number of Masses: \n'');', '', 'n = numel(drv_m);'
    't = input(''Simulation time period: \n'');', '', 't = drv_T;'
    'tStep=0.001;', '', 'tStep = drv_P.h;'
    'iterations=t/tStep;', '', sprintf('iterations=t/tStep;\niterations=round(iterations);')
    'x(1,:)=phi(:,mode);', '', sprintf('x(1,:)=drv_P.y0(1:n);\nv(1,:)=drv_P.y0(n+1:2*n);')
  };
  if strcmp(drv_variant, 'corrected')
    drv_edits(end+1, :) = {'tVector=tStep.*(1:iterations);', '', 'tVector=tStep.*(0:iterations-1);'};
  end
  eval(thesis_listing(fullfile(fileparts(mfilename('fullpath')), 'code02.m'), ...
                      '% Assume spring constants are equivalent and masses are equivelent.', ...
                      '% Plot the results', drv_edits));
  drv_K = drv_P.stiffness_matrix;
  if norm(full(K) - drv_K, 1) > 1e-12 * norm(drv_K, 1) || norm(diag(M)' - drv_P.masses(:)', 1) > 0
    error('run_code02: the K and M that Code 02 built differ from the problem''s');
  end
  thesis_write(drv_P.trajectory, drv_P.t0 + tVector, [x v], iterations - 1);
catch drv_err
  fprintf(stderr, 'error: %s\n', drv_err.message);
  exit(1);
end
