% Thesis Code 03, first two listings: one mass held by four springs in the
% plane, classical RK4 (thesis.txt lines 1360-1504), transcribed as printed.
% (Code 03's third listing, lines 1507-1553, animates a path.mat that no
% listing writes, with the function sp1 printed after Code 01; it integrates
% nothing and is not transcribed.)
%
% run_code03.m runs lines "% Initialise variables" .. the loop's "end" of
% this file with the problem's inputs (protocol of rk4core/command.py).
%
% OCR repairs (thesis.txt line: printed -> repaired; why it is OCR, not the author's):
%   1370: "1 = 0.01" -> "l = 0.01": "1 = ..." does not parse; the same OCR
%       reads the symbol l as 1 in Tables 4.4-4.5 ("Length of the spring 1
%       0.01 (m)"). (l is not used below: the springs' natural length and
%       the anchor distance are the literal 1 of dz3/dz4, erratum 4.)
%   1374-1382: "      = zeros(N,1);" / "z1" / "z2" / "       = zeros(N,1);" /
%       "      = zeros(N,1);" / "z3" / "z4" / "       = zeros(N,1);" ->
%       "z1 = zeros(N,1);" .. "z4 = zeros(N,1);": the layout tore the four
%       aligned assignments apart.
%   1385-1388: the comments "% dx/dt = z1", "% dy/dt = z2" were printed under
%       the dz1, dz2 lines (layout); kept as comment lines.
%   1389-1393: dz3 printed over five lines with no "..." continuation ->
%       one line; "w^*" -> "w*", "(z_1+1)^*(" -> "(z1+1)*(", "z_1" -> "z1",
%       "z_2" -> "z2" (LaTeX markup of the OCR). Its brackets balance and
%       w*( ... ) spans all four spring terms.
%   1395-1399: dz4 printed over five lines -> one line; "\operatorname{sqrt}"
%       -> "sqrt" (twice, LaTeX markup); and ONE closing bracket restored:
%       as printed the line has one "(" more than ")" (it does not parse).
%       The third term "+(((z2+1)*(sqrt(z1.^2 + (z2+1).^2)-1))./(sqrt(z1.^2 +
%       (z2+1).^2))" lacks the ")" that closes its own "+(" (the second and
%       fourth terms have it: "...).^2)))"); restored there. Any place after
%       the first term gives the same value.
%   1413: "b = [1 \ 2 \ 2 \ 1];" -> "b = [1 2 2 1];" ("\ " is a LaTeX space;
%       as MATLAB it would be left division and make b a scalar). The comment
%       "% RK4 coefficients" printed under it (1414) is put back on its line.
%   1415-1416: the comment's wrapped tail "Runge kutta method" -> "% Runge
%       kutta method" (bare words do not run; the layout wrapped the comment).
%   1422-1424, 1428-1430, 1440-1442: a call wrapped after "kz2(1)" / "kz2(2)"
%       lost the "," at the break -> one line with ", " (line 1431, printed
%       on one line, has it).
%   1425-1427: "kz^2(2) = dz^2(t(i) + (h/2), z^1(i) + (h/2)*kz^1(1), z^2(i)
%       ..." -> "kz2(2) = dz2(t(i) + (h/2), z1(i) + (h/2)*kz1(1), z2(i) ..."
%       (digits read as superscripts), "," restored at the break and the
%       final ")" restored ("...kz4(1);" -> "...kz4(1));").
%   1432-1433, 1435-1437: "..., z4(i) + (h/2)*kz4(2);" -> "...kz4(2));"
%       (final ")" lost; "," restored at the break).
%   1438-1439: "..., z4(i) + (h/2)*kz4(2)" -> "...kz4(2));" (")" and ";" lost).
%   1443-1444, 1446-1447, 1448-1449: "... z3(i) +" / "h*kz3(3) ,
%       z4(i)+h*kz4(3);" -> one line ending "z4(i)+h*kz4(3));" (final ")"
%       lost; line 1445 has it).
%   1481: "hold on xlabel(...); ylabel(...); title('Velocity VS Time')
%       legend(...);" -> split after "hold on" and after the title call (two
%       statements with no separator do not parse).
%   1491: "hold on xlabel('Time(s)');" -> "hold on" and "xlabel('Time(s)');".
% Not repaired (the author's, kept as printed): in dz4 the bracket after the
% first spring term closes w*( ... ), so only the first term is multiplied
% by w = -k/m (dz4 = w*T1 + T2 + T3 + T4; physics: w*(T1 + T2 + T3 + T4));
% the natural length and anchor distance 1 (m) hard-coded in dz3, dz4 and
% the spring lengths while l = 0.01 (erratum 4); the comments "%11".."%14";
% the labels of the last figure. Indentation is normalised.
clear all
close all
clc
% Initialise variables
%input Mass Value
m = 0.815
%Input for spring constants.
k = 41.5
%Input length of spring.
l = 0.01
h = 0.001;
t = 0:h:10;
N = length(t);
% Initialise vectors
z1 = zeros(N,1);
z2 = zeros(N,1);
z3 = zeros(N,1);
z4 = zeros(N,1);
w = (-k)/m;
% Initialise derivative functions
dz1 = @(t, z1, z2, z3, z4) z3;
dz2 = @(t, z1, z2, z3, z4) z4;
% dx/dt = z1
% dy/dt = z2
dz3 = @(t, z1, z2, z3, z4) w*((((z1+1)*(sqrt((z1+1).^2 + z2.^2)-1))./(sqrt((z1+1).^2 + z2.^2)))+((z1*(sqrt((z2+1).^2 + z1.^2)-1))./(sqrt((z2+1).^2 + z1.^2)))-(((1-z1)*(sqrt((1-z1).^2 + z2.^2)-1))./(sqrt((1-z1).^2 + z2.^2)))+((z1*(sqrt((1-z2).^2 + z1.^2)-1))./(sqrt((1-z2).^2 + z1.^2))));
% dz1/dt = z3
dz4 = @(t, z1, z2, z3, z4) w*(((z2*(sqrt((z1+1).^2 + z2.^2)-1)))./(sqrt((z1+1).^2 + z2.^2)))+((z2*(sqrt((1-z1).^2 + z2.^2)-1))./(sqrt((1-z1).^2 + z2.^2)))+(((z2+1)*(sqrt(z1.^2 + (z2+1).^2)-1))./(sqrt(z1.^2 + (z2+1).^2)))+(((z2-1)*(sqrt(z1.^2 + (1-z2).^2)-1))./(sqrt(z1.^2 + (1-z2).^2))); % dz2/dt = z4
%Starting conditions
z1(1) = 0.005;
z2(1) = 0;
z3(1) = 0;
z4(1) = 0;
% Initialise K vectors
kz1 = zeros(1,4); % to store K values for z1
kz2 = zeros(1,4); % to store K values for z2
kz3 = zeros(1,4); % to store K values for z3
kz4 = zeros(1,4); % to store K values for z4
b = [1 2 2 1]; % RK4 coefficients
% Iterate, computing each K value in turn, then the i+1 step values by
% Runge kutta method
for i = 1:(N-1)
    kz1(1) = dz1(t(i), z1(i), z2(i), z3(i), z4(i));
    kz2(1) = dz2(t(i), z1(i), z2(i), z3(i), z4(i));
    kz3(1) = dz3(t(i), z1(i), z2(i), z3(i), z4(i));
    kz4(1) = dz4(t(i), z1(i), z2(i), z3(i), z4(i));
    kz1(2) = dz1(t(i) + (h/2), z1(i) + (h/2)*kz1(1), z2(i) + (h/2)*kz2(1), z3(i) + (h/2)*kz3(1), z4(i) + (h/2)*kz4(1));
    kz2(2) = dz2(t(i) + (h/2), z1(i) + (h/2)*kz1(1), z2(i) + (h/2)*kz2(1), z3(i) + (h/2)*kz3(1), z4(i) + (h/2)*kz4(1));
    kz3(2) = dz3(t(i) + (h/2), z1(i) + (h/2)*kz1(1), z2(i) + (h/2)*kz2(1), z3(i) + (h/2)*kz3(1), z4(i) + (h/2)*kz4(1));
    kz4(2) = dz4(t(i) + (h/2), z1(i) + (h/2)*kz1(1), z2(i) + (h/2)*kz2(1), z3(i) + (h/2)*kz3(1), z4(i) + (h/2)*kz4(1));
    kz1(3) = dz1(t(i) + (h/2), z1(i) + (h/2)*kz1(2), z2(i) + (h/2)*kz2(2), z3(i) + (h/2)*kz3(2), z4(i) + (h/2)*kz4(2));
    kz2(3) = dz2(t(i) + (h/2), z1(i) + (h/2)*kz1(2), z2(i) + (h/2)*kz2(2), z3(i) + (h/2)*kz3(2), z4(i) + (h/2)*kz4(2));
    kz3(3) = dz3(t(i) + (h/2), z1(i) + (h/2)*kz1(2), z2(i) + (h/2)*kz2(2), z3(i) + (h/2)*kz3(2), z4(i) + (h/2)*kz4(2));
    kz4(3) = dz4(t(i) + (h/2), z1(i) + (h/2)*kz1(2), z2(i) + (h/2)*kz2(2), z3(i) + (h/2)*kz3(2), z4(i) + (h/2)*kz4(2));
    kz1(4) = dz1(t(i) + h, z1(i) + h*kz1(3), z2(i) + h*kz2(3), z3(i) + h*kz3(3) , z4(i)+h*kz4(3));
    kz2(4) = dz2(t(i) + h, z1(i) + h*kz1(3), z2(i) + h*kz2(3), z3(i) + h*kz3(3), z4(i) + h*kz4(3));
    kz3(4) = dz3(t(i) + h, z1(i) + h*kz1(3), z2(i) + h*kz2(3), z3(i) + h*kz3(3) , z4(i)+h*kz4(3));
    kz4(4) = dz4(t(i) + h, z1(i) + h*kz1(3), z2(i) + h*kz2(3), z3(i) + h*kz3(3) , z4(i)+h*kz4(3));
    z1(i+1) = z1(i) + (h/6)*sum(b.*kz1);
    z2(i+1) = z2(i) + (h/6)*sum(b.*kz2);
    z3(i+1) = z3(i) + (h/6)*sum(b.*kz3);
    z4(i+1) = z4(i) + (h/6)*sum(b.*kz4);
end
%displacments of springs
spring_1 = sqrt((z1+1).^2+ z2.^2)-1; %11
spring_4 = sqrt((z2+1).^2+ z1.^2)-1; %14
spring_2 = 1- sqrt((1-z2).^2+ z1.^2); %12
spring_3 = 1- sqrt((1-z1).^2+ z2.^2); %13
% Group together in one solution matrix
disp('Values of t z1 z2 z3 z4 spring_1 spring_2 spring_3 spring_4 ');
Answer_Matrix = [t' z1 z2 z3 z4 spring_1 spring_2 spring_3 spring_4];
%plot results
figure()
plot(t,z1,'--r','linewidth',1.5);
hold on
plot(t,z2,'-.b','linewidth',1.5);
hold on
xlabel('Time(s)');
ylabel('Displacement (m)');
title('Displacement VS Time')
legend('X direction', 'Y direction');
grid on
figure()
plot(t,z3,'--r','linewidth',1.5);
hold on
plot(t,z4,'-.b','linewidth',1.5);
hold on
xlabel('Time(s)'); ylabel('Velocity (m/s)'); title('Velocity VS Time')
legend('X direction', 'Y direction');
grid on
figure()
plot(t,spring_1,'linewidth',1);
hold on
plot(t,spring_2,'linewidth',1);
hold on
plot(t,spring_3,'linewidth',1);
hold on
plot(t,spring_4,'linewidth',1);
hold on
xlabel('Time(s)');
ylabel('Behaviour of spring (m)');
title('Behaviour of spring VS Time')
legend('Spring 1', 'Spring 2', 'Spring 3', 'Spring 4');
grid on
figure()
plot(z1,z2,'--r','linewidth',1.5);
xlabel('Time(s)');
ylabel('Velocity (m/s)');
title('Velocity VS Time')
legend('X direction', 'Y direction');
grid on
