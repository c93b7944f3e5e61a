% RUN_CODE01_ODE45  Run Code 01's ode45 program (code01_ode45.m, with the
% reconstructed testcode.m) on a protocol problem.
%
%   octave-cli --no-history --norc --quiet run_code01_ode45.m PROBLEM.json TRAJECTORY.csv [printed]
%
% The problem must be linear with the stiffness matrix of two masses between
% two walls (springs k1, k2, k3 read from it). Runs code01_ode45.m from
% "%Degree of freedom" to the ode45 call as printed (Octave's ode45 at its
% default options: RelTol 1e-3, AbsTol 1e-6), with these lines replaced:
%   M1 = 0.815, M2 = 3.099, K1 = 41.5, K2 = 138, K3 = 157.8 -> the problem's
%   dt = 1/(max_freq*20);   -> dt = problem h (the printed rule gives
%                              h = 2 pi / (20 omega_max); the harness passes it)
%   Nstep = 100;            -> Nstep = n_steps
%   time = 0:dt:Nstep*dt;   -> time = t0 + (0:Nstep)*dt
%   y0 = [0.005 0.005 0 0]; -> y0
% The printed K is the physics' (k2 between the masses): one variant only.
% Writes time, ysol and stats.json (nfev = calls of testcode).
% Any error ends the run with one line "error: ..." on stderr and exit status 1.
try
  addpath(fileparts(mfilename('fullpath')));
  [drv_P, drv_variant] = thesis_problem(argv(), 'run_code01_ode45', {'printed'});
  [drv_m, drv_k] = thesis_chain_springs(drv_P, 'run_code01_ode45');
  if numel(drv_m) ~= 2
    error('run_code01_ode45: Code 01 integrates two masses, the problem has %d', numel(drv_m));
  end
  drv_edits = {
    'M1 = 0.815', '', 'M1 = drv_m(1);'
    'M2 = 3.099', '', 'M2 = drv_m(2);'
    'K1 = 41.5', '', 'K1 = drv_k(1);'
    'K2 = 138', '', 'K2 = drv_k(2);'
    'K3 = 157.8', '', 'K3 = drv_k(3);'
    'dt = 1/(max_freq*20);', '', 'dt = drv_P.h;'
    'Nstep = 100;', '', 'Nstep = drv_P.n_steps;'
    'time = 0:dt:Nstep*dt;', '', 'time = drv_P.t0 + (0:Nstep)*dt;'
    'y0 = [0.005 0.005 0 0]; %[disp1 disp2 vol1 vol2] inatial condition', '', 'y0 = drv_P.y0(:)'';'
  };
  global testcode_nfev
  testcode_nfev = 0;
  eval(thesis_listing(fullfile(fileparts(mfilename('fullpath')), 'code01_ode45.m'), ...
                      '%Degree of freedom', 'y1 = ysol(:,1);', drv_edits));
  thesis_write(drv_P.trajectory, time, ysol, testcode_nfev);
catch drv_err
  fprintf(stderr, 'error: %s\n', drv_err.message);
  exit(1);
end
