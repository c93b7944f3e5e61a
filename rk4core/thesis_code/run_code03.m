% RUN_CODE03  Run the RK4 loop of Code 03 (code03.m) on a protocol problem.
%
%   octave-cli --no-history --norc --quiet run_code03.m PROBLEM.json TRAJECTORY.csv [printed|corrected]
%
% The problem must be model "planar4" with params.linear false (Code 03
% integrates the exact geometry). Runs code03.m from "% Initialise
% variables" to the end of the loop as printed, with these lines replaced:
%   m = 0.815 / k = 41.5 / l = 0.01  -> params.m, params.k, params.l
%   h = 0.001;                        -> h = problem h
%   t = 0:h:10;                       -> t = t0 + (0:n_steps)*h
%   z1(1) = 0.005; .. z4(1) = 0;      -> y0
% and, for the variant "corrected" only, the two right-hand sides:
%   dz3 -> the printed dz3 with the natural length / anchor distance l
%          (params.l) in place of the literal 1;
%   dz4 -> w*( all four spring terms ), with l in place of 1: the physics
%          (m y'' = -k sum_j (L_j - l) (y - a_jy) / L_j).
% "printed" keeps dz3, dz4 as printed (dz4 = w*T1 + T2 + T3 + T4, natural
% length 1 m whatever params.l says: a note on stderr when l ~= 1).
% Writes t, x, y, vx, vy at every step and stats.json (nfev = 4 evaluations
% of the state's right-hand side per step).
% Any error ends the run with one line "error: ..." on stderr and exit status 1.
try
  addpath(fileparts(mfilename('fullpath')));
  [drv_P, drv_variant] = thesis_problem(argv(), 'run_code03', {'printed', 'corrected'});
  if ~strcmp(drv_P.model, 'planar4') || drv_P.params.linear
    error('run_code03: Code 03 integrates the four-spring mass with exact geometry (model planar4, linear = false), got model %s', drv_P.model);
  end
  drv_edits = {
    'm = 0.815', '', 'm = drv_P.params.m;'
    'k = 41.5', '', 'k = drv_P.params.k;'
    'l = 0.01', '', 'l = drv_P.params.l;'
    'h = 0.001;', '', 'h = drv_P.h;'
    't = 0:h:10;', '', 't = drv_P.t0 + (0:drv_P.n_steps)*h;'
    'z1(1) = 0.005;', '', 'z1(1) = drv_P.y0(1);'
    'z2(1) = 0;', '', 'z2(1) = drv_P.y0(2);'
    'z3(1) = 0;', '', 'z3(1) = drv_P.y0(3);'
    'z4(1) = 0;', '', 'z4(1) = drv_P.y0(4);'
  };
  if strcmp(drv_variant, 'corrected')
    drv_dz3 = 'dz3 = @(t, z1, z2, z3, z4) w*((((z1+l)*(sqrt((z1+l).^2 + z2.^2)-l))./(sqrt((z1+l).^2 + z2.^2)))+((z1*(sqrt((z2+l).^2 + z1.^2)-l))./(sqrt((z2+l).^2 + z1.^2)))-(((l-z1)*(sqrt((l-z1).^2 + z2.^2)-l))./(sqrt((l-z1).^2 + z2.^2)))+((z1*(sqrt((l-z2).^2 + z1.^2)-l))./(sqrt((l-z2).^2 + z1.^2))));';
    drv_dz4 = 'dz4 = @(t, z1, z2, z3, z4) w*(((z2*(sqrt((z1+l).^2 + z2.^2)-l))./(sqrt((z1+l).^2 + z2.^2)))+((z2*(sqrt((l-z1).^2 + z2.^2)-l))./(sqrt((l-z1).^2 + z2.^2)))+(((z2+l)*(sqrt(z1.^2 + (z2+l).^2)-l))./(sqrt(z1.^2 + (z2+l).^2)))+(((z2-l)*(sqrt(z1.^2 + (l-z2).^2)-l))./(sqrt(z1.^2 + (l-z2).^2))));';
    drv_printed = fileread(fullfile(fileparts(mfilename('fullpath')), 'code03.m'));
    drv_lines = strtrim(strsplit(drv_printed, sprintf('\n')));
    drv_edits(end+1, :) = {drv_lines{strncmp(drv_lines, 'dz3 = @', 7)}, '', drv_dz3};
    drv_edits(end+1, :) = {drv_lines{strncmp(drv_lines, 'dz4 = @', 7)}, '', drv_dz4};
  elseif drv_P.params.l ~= 1
    fprintf(stderr, 'run_code03: printed Code 03 uses natural length 1 m (erratum 4); params.l = %g is not used\n', drv_P.params.l);
  end
  eval(thesis_listing(fullfile(fileparts(mfilename('fullpath')), 'code03.m'), ...
                      '% Initialise variables', '%displacments of springs', drv_edits));
  thesis_write(drv_P.trajectory, t, [z1 z2 z3 z4], 4*(N-1));
catch drv_err
  fprintf(stderr, 'error: %s\n', drv_err.message);
  exit(1);
end
